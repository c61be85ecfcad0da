"""Oracles and checkers shared by the tests: written independently of the code they check."""
