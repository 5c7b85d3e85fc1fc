"""Property tests of the export's names and texts (addon/core/export/, no Blender): for any
material, image and object names (any Unicode, control characters, up to 255 bytes, names
that sanitise alike or differ by case), the names the three formats write are unique (compared
as a case-insensitive file system compares them), each a file name the write gate takes
(core.gate.check_name: at most 255 bytes with the staging name's room, valid UTF-8, no
separator), and the documents parse: the .mtlx with xml.etree, the .gltf as JSON (encoded as
UTF-8), the .usda with USD's own parser (Blender's bundled pxr, loaded without bpy) where every
string and asset path reads back as written."""

import json
import unicodedata
import xml.etree.ElementTree as ET

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from addon.core import files
from addon.core.export import gltf, materialx, network
from addon.core.export import names as naming, usd
from addon.core.gate import check_name

# Any character at all: control characters, non-ASCII, lone surrogates (a name decoded from
# a non-UTF-8 file name) included
ANY_CHAR = st.characters(exclude_categories=())
# Characters core.paths.safe_name drops or replaces, and case: names that sanitise alike
DROPPED = "/?*:<>|\\\"' .\x00\x01\n\té漢-+"


def _cut(text: str, limit: int = 255) -> str:
    """At most ``limit`` bytes of UTF-8 (surrogates counted as 3)."""
    out, size = [], 0
    for c in text:
        n = len(c.encode("utf-8", "surrogatepass"))
        if size + n > limit:
            break
        out.append(c)
        size += n
    return "".join(out)


NAMES = st.text(ANY_CHAR, max_size=300).map(_cut)


@st.composite
def colliding_names(draw):
    """Names from one base that differ only by characters safe_name drops or by case."""
    base = draw(st.text(st.sampled_from("GgOoLlDd_1"), min_size=1, max_size=8))
    out = []
    for _ in range(draw(st.integers(2, 6))):
        chars = []
        for c in base:
            chars.append(c.swapcase() if draw(st.booleans()) else c)
            if draw(st.booleans()):
                chars.append(draw(st.sampled_from(DROPPED)))
        out.append("".join(chars))
    return out


MATERIAL_NAMES = st.one_of(st.lists(NAMES, min_size=1, max_size=6), colliding_names())
MAP = network.Texture("textures/m.png")


def _materials(names):
    return [network.Material(name, textures={"metallic": MAP}) for name in names]


def _component_ok(name: str) -> None:
    for part in name.split("/"):
        check_name(part, "a name the export writes")  # raises on a bad one
        assert len(part.encode("utf-8")) <= 255


def _unique(names) -> None:
    folded = [n.casefold() for n in names]
    assert len(set(folded)) == len(folded), names


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(MATERIAL_NAMES)
def test_material_names_are_unique_valid_file_names(names):
    """naming.export_names: one .mtlx, one USD prim name and one glTF packed image per
    material, none shared (without case), each a valid file name component."""
    mats = _materials(names)
    got = naming.export_names(mats)
    assert got == naming.export_names(mats)  # deterministic
    _unique([n.mtlx for n in got])
    _unique([n.ident for n in got])
    _unique([n.metallic_roughness for n in got] + [MAP.file])
    for n in got:
        _component_ok(n.mtlx)
        _component_ok(n.metallic_roughness)
        assert naming._INVALID.sub("", n.ident) == n.ident and not n.ident[0].isdigit()


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(MATERIAL_NAMES)
def test_gltf_packed_images_are_distinct_and_the_json_parses(names):
    """The .gltf (gltf_document, as the export encodes it): each material with a metallic map
    references its own packed image (before: two materials whose names sanitise alike
    shared one, so one map was lost), and the file is UTF-8 JSON."""
    mats = _materials(names)
    doc = gltf.gltf_document(mats)
    text = files.json_text(doc)
    back = json.loads(text.encode("utf-8").decode("utf-8"))
    uris = [
        back["images"][back["textures"][tex]["source"]]["uri"]
        for tex in (
            m["pbrMetallicRoughness"]["metallicRoughnessTexture"]["index"]
            for m in back["materials"]
        )
    ]
    _unique(uris)
    assert MAP.file.casefold() not in {u.casefold() for u in uris}
    for uri in uris:
        _component_ok(uri)
    # the per-material name agrees with the document's, given the materials exported with it
    assert [gltf.metallic_roughness_name(m, mats) for m in mats] == uris


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(NAMES, NAMES)
def test_mtlx_parses_for_any_name_and_texture_file(name, file):
    """The .mtlx of a material of any name, with a texture of any file name: well-formed XML
    (ElementTree reads it back), its material element's name valid."""
    mat = network.Material(name, textures={"albedo": network.Texture(file, "srgb_texture")})
    text = materialx.mtlx_document(mat)
    root = ET.fromstring(text.encode("utf-8"))
    (sm,) = root.iter("surfacematerial")
    assert naming._INVALID.sub("", sm.get("name")) == sm.get("name")


@settings(max_examples=300, deadline=None)
@given(st.text(ANY_CHAR, max_size=40), st.text(ANY_CHAR, max_size=20), st.integers(0, 3))
def test_texture_names_are_bounded_valid_and_unique(stem, ext, copies):
    """naming.texture_name: any stem and extension (240 characters, undecodable bytes)
    give textures/NAME, a valid component of at most 255 bytes, unique without case."""
    used, names = set(), []
    for i in range(copies + 1):
        e = "." + ext if i % 2 == 0 else "." + "x" * 240
        names.append(naming.texture_name(stem if i < 2 else stem.swapcase(), e, ".png", used))
    _unique(names)
    for n in names:
        assert n.startswith("textures/")
        _component_ok(n)


@pytest.fixture(scope="module")
def sdf():
    pxr = pytest.importorskip("pxr.Sdf", reason="Blender's bundled pxr (tests/unit/conftest.py)")
    return pxr


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(text=st.text(ANY_CHAR, max_size=60))
def test_usd_string_round_trips(sdf, text):
    """usd.usd_string: USD's parser reads back the text (quotes, backslashes, newlines,
    control characters, non-ASCII); undecodable bytes as U+FFFD."""
    layer = sdf.Layer.CreateAnonymous(".usda")
    assert layer.ImportFromString("#usda 1.0\n(\n    doc = " + usd.usd_string(text) + "\n)\n")
    assert layer.documentation == naming.utf8_text(text)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(path=st.text(ANY_CHAR, max_size=40))
def test_usd_asset_round_trips(sdf, path):
    """usd.usd_asset: any asset path reads back (an @ inside, non-ASCII), less the control
    characters no asset path holds."""
    layer = sdf.Layer.CreateAnonymous(".usda")
    text = '#usda 1.0\ndef "X"\n{\n    asset a = ' + usd.usd_asset(path) + "\n}\n"
    assert layer.ImportFromString(text)
    want = "".join(c for c in naming.utf8_text(path) if unicodedata.category(c) != "Cc")
    assert layer.GetAttributeAtPath("/X.a").default.path == want


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    names=MATERIAL_NAMES,
    objects=st.lists(NAMES, min_size=1, max_size=4),
    files_=st.lists(NAMES, min_size=1, max_size=2),
)
def test_usda_parses_and_binds_each_object_to_its_own_material(sdf, names, objects, files_):
    """The .usda of materials of any names (two of one name: a local and a linked material),
    objects of any names and textures of any file names parses with USD's parser; each
    material is its own prim, its name and library kept in customData, and each object is
    bound to the material it is on (before, materials of one name shared one binding)."""
    names = names + names[:1]  # a local and a linked material of one name
    mats = []
    for i, name in enumerate(names):
        mats.append(
            network.Material(
                name,
                textures={"albedo": network.Texture(files_[i % len(files_)], "srgb_texture")},
                objects=(objects[i % len(objects)] + f"#{i}",),
                library="//lib.blend" if i == len(names) - 1 else "",
            )
        )
    layer = sdf.Layer.CreateAnonymous(".usda")
    assert layer.ImportFromString(usd.usda_document(mats))
    prims = layer.GetPrimAtPath("/Materials").nameChildren
    assert len(prims) == len(mats)
    for prim, mat in zip(prims, mats):
        assert prim.customData["blender_name"] == naming.utf8_text(mat.name)
        assert prim.customData["blender_library"] == mat.library
    bound = {}
    for prim in layer.GetPrimAtPath("/Objects").nameChildren:
        rel = prim.relationships["material:binding"]
        bound[prim.customData["blender_name"]] = rel.targetPathList.explicitItems[0].name
    for prim, mat in zip(prims, mats):
        assert bound[naming.utf8_text(mat.objects[0])] == prim.name


def test_gltf_never_calls_a_material_exact():
    """glTF weights its Lambert diffuse by 1 - F and cannot carry the model's 0.96 (docs/model.md
    "Derived quantities"): even a Smith + Lambert material lists it as not carried, in the
    export's per-material list and in the file's extras; the MaterialX graph is exact only
    through OSL closures like Cycles' (network.EXACT)."""
    mat = network.Material("M", g_model="smith_ggx_correlated", diffuse_model="lambert")
    assert network.exact(mat) and not network.not_carried(mat)
    assert any("0.96" in n for n in gltf.gltf_not_carried(mat))
    extras = gltf.gltf_document([mat])["materials"][0]["extras"]["cook_torrance_lab"]
    assert any("0.96" in n for n in extras["not_carried"])
    assert network.EXACT == "exact in Cycles/OSL closures"
    assert "Exact in Cycles/OSL closures" in materialx.mtlx_document(mat)
