"""warpmesh.io.files.save: where it refuses to write."""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm


def test_saving_onto_a_folder_names_the_folder(tmp_path):
    m = wm.Mesh(np.eye(3), {"triangle": [[0, 1, 2]]})
    (tmp_path / "out.msh").mkdir()
    with pytest.raises(IsADirectoryError, match="the folder .*out.msh"):
        m.save(tmp_path / "out.msh")
    assert [p.name for p in tmp_path.iterdir()] == ["out.msh"]  # nothing left beside it
