"""Unity's material files without Blender (addon/core/unity/): the reader on .mat text of both
layouts and both keyword forms, .meta files old and new, a project folder's guids; what a
Standard material means for the model; the writer's .mat, .meta files and packed map; and the
round trip, writer to reader, within 1/255 (Hypothesis over the values). Fixtures are the
tests' own (tests/unity_fixtures.py)."""

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import unity_fixtures as fx

from addon.core.errors import UserError
from addon.core.export.names import utf8_text
from addon.core.export.network import Material, Texture
from addon.core.unity import mat as writer
from addon.core.unity import read, standard


def _srgb(c):
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def test_flat_layout_with_valid_keywords_and_a_second_document():
    text = fx.mat_flat(
        "Brick",
        textures={"_MainTex": (fx.G_METAL, (2, 3), (0.25, -0.5))},
        floats={"_Metallic": 0.9, "_GlossMapScale": 0.8},
        colors={"_Color": (0.8, 0.6, 0.4, 1.0)},
        keywords=("_NORMALMAP", "_METALLICGLOSSMAP"),
    )
    m = read.read_material(text, "Brick.mat")
    assert m.is_standard and m.layout == "flat" and m.name == "Brick"
    # an all-digit guid with a leading zero stays text (YAML 1.1 would read an octal number)
    assert m.texture("_MainTex").guid == fx.G_METAL
    assert m.texture("_MainTex").scale == (2.0, 3.0)
    assert m.texture("_MainTex").offset == (0.25, -0.5)
    assert m.float("_Metallic") == 0.9 and m.float("_Glossiness") == 0.5  # Standard's default
    assert m.color("_Color") == (0.8, 0.6, 0.4, 1.0)
    assert m.keywords == ("_NORMALMAP", "_METALLICGLOSSMAP")


def test_unity5_pairs_layout_with_a_keyword_string():
    text = fx.mat_pairs(
        "Old",
        textures={"_MainTex": (fx.G_ALBEDO, (4, 4), (0, 0))},
        floats={"_Metallic": 0.3, "_Glossiness": 0.65},
        colors={"_Color": (0.5, 0.25, 0.75, 1)},
        keywords=("_EMISSION", "_NORMALMAP"),
    )
    m = read.read_material(text, "Old.mat")
    assert m.layout == "pairs" and m.is_standard
    assert m.float("_Glossiness") == 0.65 and m.color("_Color") == (0.5, 0.25, 0.75, 1.0)
    assert m.texture("_MainTex").guid == fx.G_ALBEDO and m.texture("_MainTex").scale == (4, 4)
    assert m.keywords == ("_EMISSION", "_NORMALMAP")


def test_only_fileid_46_of_the_builtin_guid_is_standard():
    for file_id, is_standard in ((46, True), (45, False), (47, False)):
        m = read.read_material(fx.mat_pairs("M", shader_file_id=file_id), "M.mat")
        assert m.is_standard is is_standard
    toon = read.read_material(fx.mat_flat("T", shader="{fileID: 46, guid: " + "1" * 32 + "}"), "T")
    assert not toon.is_standard  # fileID 46 of another guid is some other shader


@pytest.mark.parametrize(
    "text, message",
    [
        ("Material: [unclosed\n  - {a: ", "is not YAML"),
        ("\0\0binary", "not a text file"),
        (fx.UNITY4, "Unity 4's layout"),
        (fx.HEADER + "--- !u!1 &1\nGameObject:\n  m_Name: x\n", "holds no Unity material"),
    ],
)
def test_bad_mat_text_is_one_line(text, message):
    with pytest.raises(UserError, match=message) as info:
        read.read_material(text, "Bad.mat")
    assert "\n" not in str(info.value)


def test_meta_old_and_new_colour_flags():
    assert read.read_meta(fx.texture_meta(fx.G_ALBEDO, srgb=True), "a").srgb
    assert not read.read_meta(fx.texture_meta(fx.G_ALBEDO, srgb=False), "a").srgb
    old = read.read_meta(fx.texture_meta(fx.G_METAL, srgb=False, old=True), "a")
    assert old.guid == fx.G_METAL and not old.srgb  # linearTexture: 1
    assert read.read_meta(fx.texture_meta(fx.G_METAL, srgb=True, old=True), "a").srgb
    # a normal map is linear whatever the flags say
    normal = read.read_meta(fx.texture_meta(fx.G_NORMAL, srgb=True, normal=True), "a")
    assert normal.normal_map and not normal.srgb


def _project(tmp_path):
    root = fx.write_project(tmp_path / "proj")
    project = standard.scan(standard.project_roots(root))
    mats = {
        read.read_material(p.read_text(), p.name).name: read.read_material(p.read_text(), p.name)
        for p in project.materials
    }
    return root, project, mats


def test_scan_finds_guids_and_materials(tmp_path):
    root, project, mats = _project(tmp_path)
    assert project.assets[fx.G_ALBEDO][0] == root / "Assets" / "Textures" / "albedo.png"
    assert set(mats) == {"Brick", "Old", "AlbedoAlpha", "Missing", "Spec", "Autodesk", "Toon"}
    assert standard.shader_label(mats["Toon"], project) == "shader Toon.shader"
    assert standard.shader_label(mats["Spec"]) == "Standard (Specular setup)"
    assert not project.problems


def test_surface_of_standard_materials(tmp_path):
    _, project, mats = _project(tmp_path)
    brick = standard.surface(mats["Brick"], project.assets)
    assert brick.albedo == pytest.approx([_srgb(c) for c in fx.BRICK_COLOR[:3]], abs=1e-9)
    assert brick.albedo_map.path.endswith("albedo.png") and brick.albedo_map.srgb
    assert brick.metallic_map.path.endswith("metal.png") and brick.metallic_map.srgb
    assert brick.smoothness_from == "metallic_map" and brick.gloss_map_scale == 0.8
    assert brick.normal_map.path.endswith("normal.png") and not brick.normal_map.srgb
    assert brick.bump_scale == 0.5 and brick.tiling == (2, 3) and brick.offset == (0.25, 0.5)
    assert any("_OcclusionMap" in n for n in brick.not_carried)
    # _SmoothnessTextureChannel 1: the albedo's alpha times _GlossMapScale; the metallic
    # map's alpha and _Glossiness ignored
    alpha = standard.surface(mats["AlbedoAlpha"], project.assets)
    assert alpha.smoothness_from == "albedo_map" and alpha.gloss_map_scale == 0.5
    assert standard.effective_smoothness(alpha, albedo_alpha=0.6, gloss_alpha=0.1) == 0.3
    old = standard.surface(mats["Old"], project.assets)
    assert old.smoothness_from == "constant" and old.smoothness == 0.65 and old.metallic == 0.3
    missing = standard.surface(mats["Missing"], project.assets)
    assert missing.albedo_map is None and fx.G_GONE in missing.warnings[0]


def _material(albedo, metallic, smoothness, maps=True):
    textures = {}
    if maps:
        textures = {
            "albedo": Texture("textures/paint.png", "srgb_texture"),
            "metallic": Texture("textures/metal.png", ""),
            "smoothness": Texture("textures/rough.png", "", invert=True),
            "normal": Texture("textures/normal.png", "", strength=0.5),
        }
    return Material(
        "Painted Metal", albedo=albedo, metallic=metallic, smoothness=smoothness, textures=textures
    )


def _read_back(out: dict, tmp_path: Path):
    """The writer's files in a folder, read back as a project: (Surface per .mat, files)."""
    for rel, content in out.items():
        path = tmp_path / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, tuple):
            assert content[0] == writer.PNG_RGBA
            path.write_bytes(fx.png_bytes(content[1]))
        else:
            path.write_bytes(content)
    for rel in out:  # the copied textures (the export copies them): stand-ins
        asset = tmp_path / rel[: -len(".meta")]
        if rel.startswith("textures/") and rel.endswith(".meta") and not asset.exists():
            asset.write_bytes(fx.png_bytes(np.ones((1, 1, 4))))
    project = standard.scan([tmp_path])
    surfaces = [
        standard.surface(read.read_material(p.read_text(), p.name), project.assets)
        for p in project.materials
    ]
    return surfaces


def test_writer_files_and_metas(tmp_path):
    rough = np.full((2, 2, 3), 0.25, np.float32)
    metal = np.zeros((4, 4, 3), np.float32)
    metal[:, 2:] = 1.0
    mat = _material((0.2, 0.4, 0.6), 0.0, 0.5)
    out = writer.unity_outputs(
        [mat],
        ["textures/paint.png", "textures/normal.png"],
        {"textures/rough.png": rough, "textures/metal.png": metal},
        namespace="scene",
    )
    assert set(out) == {
        "Painted_Metal.mat",
        "Painted_Metal.mat.meta",
        "textures.meta",
        "textures/paint.png.meta",
        "textures/normal.png.meta",
        "textures/Painted_Metal_metallic_gloss.png",
        "textures/Painted_Metal_metallic_gloss.png.meta",
    }
    again = writer.unity_outputs(
        [mat], (), {"textures/rough.png": rough, "textures/metal.png": metal}, namespace="scene"
    )
    assert again["Painted_Metal.mat"] == out["Painted_Metal.mat"]  # stable guids
    other = writer.unity_outputs(
        [mat], (), {"textures/rough.png": rough, "textures/metal.png": metal}, namespace="b"
    )
    assert other["Painted_Metal.mat"] != out["Painted_Metal.mat"]
    normal = read.read_meta(out["textures/normal.png.meta"].decode(), "n")
    assert normal.normal_map and not normal.srgb
    assert read.read_meta(out["textures/paint.png.meta"].decode(), "p").srgb
    packed_meta = read.read_meta(out["textures/Painted_Metal_metallic_gloss.png.meta"].decode(), "")
    assert not packed_meta.srgb and not packed_meta.normal_map
    kind, px = out["textures/Painted_Metal_metallic_gloss.png"]
    assert px.shape == (4, 4, 4)
    assert px[..., 0] == pytest.approx(metal[..., 0])  # R = metallic
    assert px[..., 3] == pytest.approx(np.full((4, 4), 0.75))  # A = 1 - roughness
    m = read.read_material(out["Painted_Metal.mat"].decode(), "x")
    assert set(m.keywords) == {"_METALLICGLOSSMAP", "_NORMALMAP"}
    assert m.color("_Color") == (1.0, 1.0, 1.0, 1.0)  # the albedo map holds the colour
    assert m.float("_BumpScale") == 0.5 and m.float("_GlossMapScale") == 1.0


def test_an_srgb_metallic_map_is_decoded_into_the_linear_packed_map():
    mat = Material("M", textures={"metallic": Texture("textures/m.png", "srgb_texture")})
    out = writer.unity_outputs([mat], (), {"textures/m.png": np.full((1, 1, 3), 0.5)})
    px = out["textures/M_metallic_gloss.png"][1]
    assert px[0, 0, 0] == pytest.approx(_srgb(0.5), abs=1e-6)
    assert px[0, 0, 3] == pytest.approx(0.5)  # the constant smoothness


@settings(max_examples=40, deadline=None)
@given(
    albedo=st.tuples(*[st.floats(0.0, 1.0)] * 3),
    metallic=st.floats(0.0, 1.0),
    smoothness=st.floats(0.0, 1.0),
    name=st.text(min_size=1, max_size=20).filter(lambda s: s.strip()),
)
def test_round_trip_of_constants(tmp_path_factory, albedo, metallic, smoothness, name):
    mat = Material(name, albedo=albedo, metallic=metallic, smoothness=smoothness)
    out = writer.unity_outputs([mat])
    (s,) = _read_back(out, tmp_path_factory.mktemp("rt"))
    assert s.name == utf8_text(name)
    assert s.albedo == pytest.approx(albedo, abs=1 / 255)
    assert s.metallic == pytest.approx(metallic, abs=1 / 255)
    assert s.smoothness == pytest.approx(smoothness, abs=1 / 255)
    assert s.albedo_map is None and s.metallic_map is None and s.normal_map is None


@settings(max_examples=15, deadline=None)
@given(
    metal=st.lists(st.integers(0, 255), min_size=4, max_size=4),
    rough=st.lists(st.integers(0, 255), min_size=4, max_size=4),
    strength=st.floats(0.0, 2.0),
)
def test_round_trip_of_maps(tmp_path_factory, metal, rough, strength):
    metal_px = np.repeat(np.array(metal, np.float32).reshape(2, 2, 1) / 255, 3, axis=2)
    rough_px = np.repeat(np.array(rough, np.float32).reshape(2, 2, 1) / 255, 3, axis=2)
    mat = _material((0.5, 0.5, 0.5), 0.0, 0.5)
    mat = Material(
        mat.name,
        textures={**mat.textures, "normal": Texture("textures/normal.png", "", strength=strength)},
    )
    out = writer.unity_outputs(
        [mat], (), {"textures/metal.png": metal_px, "textures/rough.png": rough_px}
    )
    folder = tmp_path_factory.mktemp("rt")
    (s,) = _read_back(out, folder)
    assert s.albedo_map.path.endswith("paint.png") and s.albedo == (1.0, 1.0, 1.0)
    assert s.normal_map.path.endswith("normal.png") and s.bump_scale == pytest.approx(strength)
    assert s.smoothness_from == "metallic_map" and s.gloss_map_scale == 1.0
    assert not s.metallic_map.srgb
    packed = out["textures/Painted_Metal_metallic_gloss.png"][1]
    assert packed[..., 0] == pytest.approx(metal_px[..., 0], abs=1 / 255)
    assert packed[..., 3] == pytest.approx(1 - rough_px[..., 0], abs=1 / 255)


def test_names_are_unique_files():
    out = writer.unity_outputs([Material("Gold"), Material("gold"), Material("Go/ld")])
    mats = sorted(k for k in out if k.endswith(".mat"))
    assert len({k.casefold() for k in mats}) == 3
    names = {read.read_material(out[k].decode(), k).name for k in mats}
    assert names == {"Gold", "gold", "Go/ld"}


def test_unityparser_reads_what_the_writer_writes(tmp_path):
    """An independent reader of Unity's YAML (unityparser) loads every .mat the writer
    writes: the Standard shader, the values within 1/255, each texture's guid that of a
    .meta written beside it, the normal map's .meta a normal map."""
    from unityparser import UnityDocument

    metal = np.zeros((2, 2, 3), np.float32)
    rough = np.full((2, 2, 3), 0.25, np.float32)
    painted = _material((0.2, 0.4, 0.6), 0.0, 0.5)
    gold = Material("Gold", albedo=(1.0, 0.766, 0.336), metallic=0.9, smoothness=0.3)
    out = writer.unity_outputs(
        [painted, gold], (), {"textures/rough.png": rough, "textures/metal.png": metal}
    )
    _read_back(out, tmp_path)
    metas = {read.read_meta(p.read_text(), p.name).guid: p for p in tmp_path.rglob("*.meta")}
    for name in ("Painted_Metal.mat", "Gold.mat"):
        m = UnityDocument.load_yaml(str(tmp_path / name)).entry
        assert type(m).__name__ == "Material"
        assert (int(m.m_Shader["fileID"]), m.m_Shader["guid"]) == (46, fx.BUILTIN)
        props = m.m_SavedProperties
        floats = {k: float(v) for entry in props["m_Floats"] for k, v in entry.items()}
        colors = {k: v for entry in props["m_Colors"] for k, v in entry.items()}
        textures = {k: v for entry in props["m_TexEnvs"] for k, v in entry.items()}
        if name == "Gold.mat":
            assert floats["_Metallic"] == pytest.approx(0.9, abs=1 / 255)
            assert floats["_Glossiness"] == pytest.approx(0.3, abs=1 / 255)
            rgb = [float(colors["_Color"][c]) for c in "rgb"]
            encoded = [1.055 * c ** (1 / 2.4) - 0.055 for c in gold.albedo]  # the sRGB curve
            assert rgb == pytest.approx(encoded, abs=1 / 255)
            continue
        for prop in ("_MainTex", "_BumpMap", "_MetallicGlossMap"):
            guid = textures[prop]["m_Texture"]["guid"]
            assert guid in metas, (prop, guid)
        bump = metas[textures["_BumpMap"]["m_Texture"]["guid"]]
        meta = UnityDocument.load_yaml(str(bump)).entry
        assert int(meta["TextureImporter"]["textureType"]) == 1
