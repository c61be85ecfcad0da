"""The warpmesh command line: ``warpmesh mesh | curve | domain | info | transform | ...``."""

from warpmesh.cli.commands import main as main

__all__ = ["main"]
