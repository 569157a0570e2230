"""CoACD decomposition: concave objects keep their cavity, convex ones stay one part."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from objects_fixtures import COARSE_COACD, mug_like

from graspstab.objects.decompose import convex_decomposition, inside_any_part


def test_mug_keeps_cavity() -> None:
    cup = mug_like()
    parts = convex_decomposition(cup, COARSE_COACD)
    assert 2 <= len(parts) <= COARSE_COACD["max_convex_hull"]
    assert all(p.is_watertight and p.is_convex and p.volume > 0 for p in parts)
    cavity_centre = np.array([[0.0, 0.0, 0.05]])
    assert not inside_any_part(parts, cavity_centre)[0]
    # the wall and the floor are covered
    assert inside_any_part(parts, [[0.036, 0.0, 0.04], [0.0, 0.0, 0.005]], tol=1e-3).all()


def test_box_is_one_part() -> None:
    box = trimesh.creation.box([0.05, 0.06, 0.07])
    parts = convex_decomposition(box, COARSE_COACD)
    assert len(parts) == 1
    assert parts[0].volume == pytest.approx(box.volume, rel=1e-3)


def test_unknown_parameter_rejected() -> None:
    with pytest.raises(ValueError, match="unknown CoACD"):
        convex_decomposition(trimesh.creation.box([0.1, 0.1, 0.1]), {"tresh": 0.1})
