"""The adaptive covering-up [FG §16.4.1]: octree, per-cell tapes, contouring of the leaves, QEF vertex placement."""
