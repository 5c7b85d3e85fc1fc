"""Panels and menu entries: Material Properties > Cook-Torrance, the 3D Viewport sidebar's
Cook-Torrance tab, and the shader editor's Add menu entry."""

from __future__ import annotations

import bpy

from ..blender import convert, light_sync, model_node, renderer, scene_lights
from .operators import (
    PLOT_IMAGE,
    draw_import_menu,
    CTLAB_OT_add_node_group,
    CTLAB_OT_add_texture,
    CTLAB_OT_bake_environment,
    CTLAB_OT_brdf_plot,
    CTLAB_OT_export_materialx,
    CTLAB_OT_export_unity,
    CTLAB_OT_build_sphere_matrix,
    CTLAB_OT_cancel_comparison,
    CTLAB_OT_convert_to_cook_torrance,
    CTLAB_OT_convert_to_principled,
    CTLAB_OT_new_material,
    CTLAB_OT_render_comparison,
    CTLAB_OT_scene_comparison,
    CTLAB_OT_set_view_all,
    CTLAB_OT_switch_implementation,
    CTLAB_OT_sync_lighting,
    JOBS,
)
from ..core.model import LIGHT_SLOTS, ggx_alpha, perceptual_roughness
from .labels import IMPLEMENTATION_LABELS, transport_notes


def _source_label(sock: bpy.types.NodeSocket) -> str:
    node = sock.links[0].from_node
    image = getattr(node, "image", None)
    if image is None and node.bl_idname == "ShaderNodeNormalMap" and node.inputs["Color"].is_linked:
        image = getattr(node.inputs["Color"].links[0].from_node, "image", None)
    name = node.label or node.name
    return f"{name}: {image.name}" if image is not None else name


def _input_row(layout, sock, text: str) -> None:
    if sock.is_linked:
        row = layout.row()
        row.label(text=text)
        row.label(text=_source_label(sock), icon='LINKED')
    else:
        layout.prop(sock, "default_value", text=text)


def _image_node(sock):
    """The image texture feeding a socket (directly or through a Normal Map), if any."""
    if not sock.is_linked:
        return None
    node = sock.links[0].from_node
    if node.bl_idname == "ShaderNodeNormalMap" and node.inputs["Color"].is_linked:
        node = node.inputs["Color"].links[0].from_node
    return node if node.bl_idname == "ShaderNodeTexImage" else None


def _transport_box(layout, scene, node) -> None:
    """What the material sees in its light transport, and the render settings that keep the
    scene transport from being exact."""
    options = {
        k: model_node.get_option(node, k)
        for k in ("light_transport", "view", "units", "g_model", "diffuse_model", "energy")
    }
    box = layout.box()
    for i, line in enumerate(transport_notes(model_node.implementation(node), **options)):
        box.label(text=line, icon='LIGHT' if i == 0 else 'BLANK1')
    if options["light_transport"] == "scene":
        inexact = renderer.inexact_path_tracing(scene) if scene.render.engine == 'CYCLES' else []
        if inexact:
            box.label(
                text="Not exact with " + ", ".join(inexact) + " (Render Properties > Light Paths)",
                icon='ERROR',
            )
        depth = model_node.transport_input(node, "correction_depth")
        box.prop(depth, "default_value", text="Correction Depth")
        box.prop(scene, "ctlab_residual_pass")


class CTLAB_PT_material(bpy.types.Panel):
    """Material Properties > Cook-Torrance: the model's inputs, view and switches."""

    bl_label = "Cook-Torrance"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "material"

    @classmethod
    def poll(cls, context):
        return context.object is not None or getattr(context, "material", None) is not None

    def draw(self, context):
        layout = self.layout
        mat = getattr(context, "material", None)
        node = model_node.find(mat)
        if node is None:
            layout.label(
                text="This material does not use the Cook-Torrance model"
                if mat is not None
                else "No material",
                icon='INFO',
            )
            if mat is not None and convert.surface_principled(mat) is not None:
                layout.operator(
                    CTLAB_OT_convert_to_cook_torrance.bl_idname, icon='SHADING_RENDERED'
                ).scope = 'ACTIVE'
            layout.operator(CTLAB_OT_new_material.bl_idname, icon='ADD')
            return
        scene = context.scene
        layout.use_property_split = True
        col = layout.column()
        albedo = model_node.surface_input(node, "albedo")
        _input_row(col, albedo, "Albedo")
        tex = _image_node(albedo)
        if tex is not None:
            col.template_ID(tex, "image", new="image.new", open="image.open")
        elif not albedo.is_linked:
            col.operator(
                CTLAB_OT_add_texture.bl_idname, text="Add Albedo Texture", icon='TEXTURE'
            ).slot = "albedo"
        _input_row(col, model_node.surface_input(node, "metallic"), "Metallic")
        smooth = model_node.surface_input(node, "smoothness")
        _input_row(col, smooth, "Smoothness")
        if smooth.is_linked:
            col.label(text="Roughness = 1 - smoothness, per texel")
        else:
            pr = perceptual_roughness(smooth.default_value)
            col.label(text=f"Roughness {pr:.3f}   GGX alpha {ggx_alpha(pr):.4f}")
        normal = model_node.surface_input(node, "normal")
        if normal.is_linked and normal.links[0].from_node.bl_idname != "ShaderNodeNewGeometry":
            _input_row(col, normal, "Normal")
            tex = _image_node(normal)
            if tex is not None:
                col.template_ID(tex, "image", open="image.open")
        else:
            row = col.row()
            row.label(text="Normal: geometry")
            row.operator(
                CTLAB_OT_add_texture.bl_idname, text="Add Normal Map", icon='NORMALS_FACE'
            ).slot = "normal"

        col = layout.column(heading="Model")
        col.prop(mat, "ctlab_view")
        col.prop(mat, "ctlab_g_model")
        col.prop(mat, "ctlab_diffuse_model")
        col.prop(mat, "ctlab_units")
        col.prop(mat, "ctlab_energy")
        col.prop(mat, "ctlab_ibl")
        col.prop(mat, "ctlab_light_transport")
        _transport_box(layout, scene, node)
        wm = context.window_manager
        row = layout.row()
        row.operator(CTLAB_OT_brdf_plot.bl_idname, icon='GRAPH')
        row.operator(
            CTLAB_OT_export_materialx.bl_idname, text="MaterialX", icon='EXPORT'
        ).scope = 'ACTIVE'
        row.operator(CTLAB_OT_export_unity.bl_idname, text="Unity", icon='EXPORT').scope = 'ACTIVE'
        if wm.ctlab_plot_state == "running":
            row.label(text=f"plotting: {wm.ctlab_plot_message}", icon='TIME')
        elif wm.ctlab_plot_state == "done":
            row.label(text=f"Image Editor: {PLOT_IMAGE}", icon='IMAGE_DATA')
        elif wm.ctlab_plot_state == "failed":
            row.label(text=wm.ctlab_plot_message, icon='ERROR')

        impl = model_node.implementation(node)
        box = layout.box()
        box.label(
            text=f"Implementation: {IMPLEMENTATION_LABELS[impl][0]}",
            icon='SCRIPT' if impl == "osl" else 'NODETREE',
        )
        if impl == "osl":
            reason = model_node.osl_unavailable_reason(scene)
            if reason:
                box.label(text=f"OSL cannot run: {reason}", icon='ERROR')
            op = box.operator(
                CTLAB_OT_switch_implementation.bl_idname, text="Use Node Group", icon='NODETREE'
            )
            op.target = "nodes"
        else:
            box.label(text="Reference indirect light needs the OSL shader")
            op = box.operator(
                CTLAB_OT_switch_implementation.bl_idname, text="Use OSL Shader", icon='SCRIPT'
            )
            op.target = "osl"

        box = layout.box()
        sun = light_sync.key_sun(scene)
        box.label(
            text=f"Key light: {sun.name}" if sun else "Key light: none (no Sun in the scene)",
            icon='LIGHT_SUN',
        )
        box.prop(scene, "ctlab_sun")
        used, unused = scene_lights.scene_lights(scene, exclude=sun)
        box.label(
            text=f"Other lights: {len(used)} shaded (of {LIGHT_SLOTS} slots)"
            if used
            else "Other lights: none",
            icon='LIGHT',
        )
        for obj in used:
            problems = scene_lights.unsupported(obj)
            box.label(
                text=f"  {obj.name}"
                + (f" (not followed: {', '.join(problems)})" if problems else ""),
                icon='ERROR' if problems else 'DOT',
            )
        if unused:
            box.label(
                text=f"Not shaded (more lights than slots; the last by Suns first, "
                f"then power): "
                f"{', '.join(o.name for o in unused)}",
                icon='ERROR',
            )
        if impl == "nodes" and (used or sun):
            box.label(text="The node group's lights cast no shadows (it cannot trace)", icon='INFO')
        box.label(text=light_sync.world_label(scene), icon='WORLD')
        error = light_sync.last_error.get(scene.name)
        if error:
            box.label(text=error, icon='ERROR')
        box.operator(CTLAB_OT_sync_lighting.bl_idname, icon='FILE_REFRESH')
        layout.operator(
            CTLAB_OT_convert_to_principled.bl_idname, icon='SHADING_RENDERED'
        ).scope = 'ACTIVE'


class _Sidebar:
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Cook-Torrance"


class CTLAB_PT_sidebar(_Sidebar, bpy.types.Panel):
    """3D Viewport > Sidebar > Cook-Torrance: the sphere matrix and the environment bake."""

    bl_label = "Cook-Torrance Lab"

    def draw(self, context):
        layout = self.layout
        layout.operator(CTLAB_OT_build_sphere_matrix.bl_idname, icon='MATSPHERE')
        layout.operator(CTLAB_OT_bake_environment.bl_idname, icon='WORLD')
        bake = context.scene.get("ctlab_ibl_bake")
        if bake:
            layout.label(text=f"Baked: {bpy.path.basename(bake)}", icon='CHECKMARK')


class CTLAB_PT_sidebar_materials(_Sidebar, bpy.types.Panel):
    """Every Cook-Torrance material at once: view, lighting, conversion."""

    bl_label = "Materials"
    bl_parent_id = "CTLAB_PT_sidebar"

    def draw(self, context):
        layout = self.layout
        count = sum(1 for _ in model_node.model_materials())
        layout.label(text=f"{count} Cook-Torrance material{'s' * (count != 1)}")
        layout.operator_menu_enum(
            CTLAB_OT_set_view_all.bl_idname, "view", text="Set View on All", icon='HIDE_OFF'
        )
        layout.operator(CTLAB_OT_new_material.bl_idname, icon='ADD')
        layout.prop(context.scene, "ctlab_sun")
        layout.prop(context.scene, "ctlab_residual_pass")
        layout.operator(CTLAB_OT_sync_lighting.bl_idname, icon='FILE_REFRESH')
        row = layout.row(align=True)
        row.operator(CTLAB_OT_export_materialx.bl_idname, text="Export MaterialX", icon='EXPORT')
        row.operator(CTLAB_OT_export_unity.bl_idname, text="Export Unity", icon='EXPORT')
        col = layout.column(align=True)
        col.label(text="Selected objects:")
        col.operator(CTLAB_OT_convert_to_cook_torrance.bl_idname).scope = 'SELECTED'
        col.operator(CTLAB_OT_convert_to_principled.bl_idname).scope = 'SELECTED'


class CTLAB_PT_sidebar_comparison(_Sidebar, bpy.types.Panel):
    """The batch comparison against Principled BSDF, in a background process."""

    bl_label = "Comparison"
    bl_parent_id = "CTLAB_PT_sidebar"

    def draw(self, context):
        layout = self.layout
        wm = context.window_manager
        job = JOBS.get("comparison")
        state = job.state if job is not None else ""
        if state in ("running", "cancelling"):
            layout.progress(
                factor=wm.ctlab_job_progress, type='BAR', text=wm.ctlab_job_message or "running"
            )
            layout.operator(CTLAB_OT_cancel_comparison.bl_idname, icon='CANCEL')
            return
        layout.operator(CTLAB_OT_render_comparison.bl_idname, icon='RENDER_RESULT')
        layout.operator(CTLAB_OT_scene_comparison.bl_idname, icon='SCENE_DATA')
        if state == "done":
            layout.operator(
                "wm.url_open", text="Open Report", icon='HELP'
            ).url = job.report.as_uri()
        elif state in ("failed", "cancelled"):
            layout.label(
                text=f"{state.title()}: {job.message}",
                icon='ERROR' if state == "failed" else 'INFO',
            )


def draw_add_menu(self, context):
    """Shader editor > Add: the Cook-Torrance Lab node group."""
    space = getattr(context, "space_data", None)
    if getattr(space, "tree_type", "ShaderNodeTree") != "ShaderNodeTree":
        return
    self.layout.separator()
    self.layout.operator(CTLAB_OT_add_node_group.bl_idname, icon='NODETREE')


PANELS = (
    CTLAB_PT_material,
    CTLAB_PT_sidebar,
    CTLAB_PT_sidebar_materials,
    CTLAB_PT_sidebar_comparison,
)
MENU_ENTRIES = (("NODE_MT_add", draw_add_menu), ("TOPBAR_MT_file_import", draw_import_menu))
