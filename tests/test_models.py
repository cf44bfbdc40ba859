"""The committed planar-arm URDFs are exactly what their generator writes."""

import importlib.util

import pytest

from app.scene.files import ROOT


@pytest.mark.parametrize("links", [3, 5, 7])
def test_planar_arm_urdf_matches_generator(links):
    spec = importlib.util.spec_from_file_location("make_planar_arms", ROOT / "robots" / "make_planar_arms.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert (ROOT / "robots" / f"planar_arm_{links}.urdf").read_text() == module.planar_arm_urdf(links)
