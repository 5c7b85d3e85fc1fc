"""The model as MaterialX (addon/core/export/), without Blender: every switch combination's
document passes MaterialX's own validate() (PyPI materialx 1.39.5, in a child process:
tests/materialx_check.py), the nodedef's inputs are the model's surface inputs
(core.model.SURFACE), and the glTF packing and names follow docs/model.md. The equivalence
renders are tests/render/test_export.py."""

import itertools
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from materialx_check import materialx_check

from addon.core.export import gltf, maps, materialx, network
from addon.core.export import names as naming
from addon.core.model import DIFFUSE_MODELS, ENERGY_MODES, G_MODELS, SURFACE

TEXTURES = {
    "albedo": network.Texture("textures/a.png", "srgb_texture"),
    "metallic": network.Texture("textures/m.png"),
    "smoothness": network.Texture("textures/r.png", invert=True),
    "normal": network.Texture("textures/n.png", strength=0.5),
}


COMBOS = list(itertools.product(G_MODELS, DIFFUSE_MODELS, ENERGY_MODES, (False, True)))


def test_every_document_validates(tmp_path):
    """Each combination's .mtlx is valid for MaterialX 1.39.5 and turned into OSL by its
    generator (a misspelt input, a wrong type or a dangling connection fails validate());
    a name MaterialX cannot hold is made valid."""
    paths = []
    for i, (g_model, diffuse, energy, textured) in enumerate(COMBOS):
        mat = network.Material(
            "Mat 1/é",
            albedo=(0.9, 0.5, 0.3),
            metallic=0.4,
            smoothness=0.6,
            g_model=g_model,
            diffuse_model=diffuse,
            energy=energy,
            textures=TEXTURES if textured else {},
        )
        paths.append(tmp_path / f"{i}.mtlx")
        paths[-1].write_text(materialx.mtlx_document(mat), encoding="utf-8")
    checked = materialx_check(paths)
    for path, combo in zip(paths, COMBOS):
        r = checked[str(path)]
        assert r["version"] == "1.39.5"
        assert r["valid"], (combo, r["message"])
        assert "generalized_schlick_bsdf(" in r["osl"], combo
        assert '<surfacematerial name="Mat_1__"' in path.read_text(encoding="utf-8")


def test_nodedef_inputs_are_the_models_surface_inputs():
    """One home: the nodedef carries core.model's surface inputs, plus the diffuse switch."""
    names = [name for name, *_ in network.NODEDEF_INPUTS]
    assert names == [i.key for i in SURFACE] + ["diffuse_lambert"]
    root = ET.fromstring(materialx.mtlx_document(network.Material("m")))
    nodedef = root.find("nodedef")
    assert [e.get("name") for e in nodedef.findall("input")] == names


def test_exact_only_for_smith_without_compensation():
    for g, e in itertools.product(G_MODELS, ENERGY_MODES):
        mat = network.Material("m", g_model=g, energy=e)
        assert network.exact(mat) == (g == "smith_ggx_correlated" and e == "none")
        assert bool(network.not_carried(mat)) != network.exact(mat)


def test_gltf_factors_and_packed_metallic_roughness():
    """roughnessFactor = 1 - smoothness; a packed map's factor is 1; G = roughness (the map
    itself when it fed smoothness through 1 - x, else 1 - map), B = metallic."""
    plain = gltf.gltf_document([network.Material("p", metallic=0.25, smoothness=0.7)])
    pbr = plain["materials"][0]["pbrMetallicRoughness"]
    assert pbr["roughnessFactor"] == pytest.approx(0.3) and pbr["metallicFactor"] == 0.25
    mat = network.Material("t", textures=TEXTURES)
    pbr = gltf.gltf_document([mat])["materials"][0]["pbrMetallicRoughness"]
    assert pbr["metallicFactor"] == 1.0 and pbr["roughnessFactor"] == 1.0
    metal, rough_map = np.full((2, 2), 0.2), np.full((4, 4), 0.7)
    px = maps.metallic_roughness_pixels(metal, rough_map, invert=True)
    assert px.shape == (4, 4, 3)
    assert np.allclose(px[..., 1], 0.7) and np.allclose(px[..., 2], 0.2)
    px = maps.metallic_roughness_pixels(None, rough_map, invert=False)
    assert np.allclose(px[..., 1], 0.3) and np.allclose(px[..., 2], 1.0)


def test_names_are_valid_and_unique():
    used = set()
    assert naming.valid_name("1 a", used) == "_1_a"
    assert naming.valid_name("1 a", used) == "_1_a_2"
    assert naming.valid_name("", used) == "material"
