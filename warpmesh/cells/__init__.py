"""The cell vocabulary: types, reference cells, topology, quality and validity checks (the bottom layer)."""
