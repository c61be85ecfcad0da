"""Numbering [FG §17.4]: node renumbering, element colouring, node graphs, higher-order nodes."""
