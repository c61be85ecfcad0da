"""Helpers shared by every stage: one ``unique_rows``, one set of argument validators, the
thread helpers of CPU launches. Private to warpmesh; no module here imports a stage."""
