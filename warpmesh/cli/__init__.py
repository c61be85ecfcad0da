"""The warpmesh command line."""
