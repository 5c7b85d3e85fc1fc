"""The add-on's words for the model in Blender's interface: the names and tooltips of the
implementations, shaders, light transports, IBL modes, switches and views, and the material
panel's notes on the light transport. The values themselves are core/model/words.py's; like
Cycles' enums.py, the words a person reads live beside the UI that shows them.
"""

from __future__ import annotations

from ..core.model import ENERGY_MODES, SCENE_EXACT_G, SCENE_VIEWS, UNITS

IMPLEMENTATION_LABELS = {
    "osl": (
        "OSL Shader",
        "The OSL shader: Cycles on the CPU with Open Shading Language on; "
        "also offers the reference (Monte Carlo) indirect light",
    ),
    "nodes": ("Node Group", "The shader-node group: Cycles (CPU or GPU, SVM or OSL) and EEVEE"),
}
# The renders' names in reports and the comparison operators
SHADER_LABELS = {
    "osl": ("Cook-Torrance (OSL)", "The OSL shader (Cycles on the CPU)"),
    "nodes": ("Cook-Torrance (Node Group)", "The node group (Cycles and EEVEE)"),
    "principled": ("Principled BSDF", "Blender's Principled BSDF, the reference"),
}

LIGHT_TRANSPORT_LABELS = {
    "lab": (
        "Lab",
        "The model lights itself from the world's HDRI, the key Sun and the light "
        "slots, exactly (term views, the matrix, parity; the command line's default); "
        "other objects are not seen",
    ),
    "scene": (
        "Scene",
        "Path traced by Cycles: reflects other objects, receives bounce and "
        "mesh-emitter light, any world; exact for the world and the lights (the "
        "default of materials made in the UI)",
    ),
}
LAB_ONLY = " (Lab transport; Scene path traces the world)"
IBL_LABELS = {
    "reference": ("Reference", "Monte Carlo integration against the HDRI" + LAB_ONLY),
    "split_sum": ("Split-Sum", "Pre-filtered levels and the DFG table (baked, cached)" + LAB_ONLY),
    "unity": ("Unity", "Unity's reflection-probe approximation (baked, cached)" + LAB_ONLY),
    "split_sum_corrected": (
        "Split-Sum Corrected",
        "The split-sum toward the lobe's dominant direction "
        "(Lagarde and de Rousiers 2014; baked, cached)" + LAB_ONLY,
    ),
}

# The switches' and views' names in the UI (a value not listed is its name, title-cased).
OPTION_LABELS = {
    "cook_torrance": "Cook-Torrance",
    "smith_ggx_correlated": "Smith (height-correlated)",
    "unity_smith_joint": "Unity (Smith joint approximation)",
    "disney": "Disney",
    "lambert": "Lambert",
    "physical": "Physical",
    "unity": "Unity",
    "none": "Single Scattering",
    "compensated": "Compensated",
    "NdotL": "N·L",
    "NdotV": "N·V",
    "NdotH": "N·H",
    "VdotH": "V·H",
    "D": "D",
    "F": "F",
    "G": "G",
    "spec_color": "Specular Colour",
    "specular_brdf": "Specular BRDF",
    "diffuse_brdf": "Diffuse BRDF",
}


def label(value: str) -> str:
    """A switch's or a view's name in the UI."""
    return (
        OPTION_LABELS.get(value)
        or IBL_LABELS.get(value, (None,))[0]
        or LIGHT_TRANSPORT_LABELS.get(value, (None,))[0]
        or value.replace("_", " ").title()
    )


def transport_notes(
    impl: str,
    light_transport: str,
    view: str,
    units: str,
    g_model: str,
    diffuse_model: str,
    energy: str,
) -> list:
    """What the material sees in its light transport, in words, for the material panel
    (docs/model.md "Light transport"); ``impl`` "osl" or "nodes"."""
    if light_transport == "lab":
        return [
            "Lab: lit by the world's HDRI, the key Sun and the light slots, computed by "
            "the model itself and shown as emission (exact).",
            "It does not see other objects, bounce light or mesh emitters.",
            "Term views and Unity units need Lab: a term view is a BRDF value, not light, "
            "and Unity's pi on direct light has no closure.",
            "New materials made in the UI use Scene.",
        ]
    notes = [
        "Scene: path traced by Cycles like any material: reflects other objects, gets "
        "bounce light, mesh emitters, every light and any world (the UI's default)."
    ]
    if view not in SCENE_VIEWS:
        notes.append(
            f"The view {view!r} is the lab's: a term view is a BRDF value, not light, "
            "and a path tracer cannot split direct from indirect inside a material "
            "(Cycles' render passes do)."
        )
    if units != UNITS[0]:
        notes.append(
            "Unity units exist in Lab only (pi on direct light has no closure): "
            "this material renders in Lab."
        )
    exact = g_model == SCENE_EXACT_G and energy == ENERGY_MODES[0]
    if impl == "osl":
        if exact:
            notes.append(
                "Exact: Cycles' closures are this model (GGX, Schlick, Smith G, "
                f"{'Lambert' if diffuse_model == 'lambert' else 'Burley'} diffuse)."
            )
        else:
            notes.append(
                "Exact for the world's HDRI and the lights (a correction emission); "
                "light from other objects sees Smith's G without compensation."
            )
    else:
        parts = [
            p
            for p, on in (
                ("the G", g_model != SCENE_EXACT_G),
                ("Disney diffuse", diffuse_model != "lambert"),
                ("compensation", energy != ENERGY_MODES[0]),
            )
            if on
        ]
        notes.append(
            "Node group: Metallic BSDF + Diffuse BSDF"
            + (
                f" plus a correction emission for {', '.join(parts)}: exact for the lights, a "
                "split-sum for the world; light from other objects sees Smith's G and Lambert."
                if parts
                else ": exactly this model."
            )
        )
        notes.append("EEVEE lights these closures approximately (probes, screen tracing).")
    return notes
