"""Materials: a new Cook-Torrance material, the node group and textures added, the
implementation switched, conversion from and to Principled BSDF, one view for all."""

from __future__ import annotations

import bpy
from bpy.props import EnumProperty

from ...blender import light_sync, model_node
from ...core.errors import UserError
from ...core.model import ARTIST, DEFAULT_TRANSPORT
from .. import preferences
from ..labels import IMPLEMENTATION_LABELS
from ..properties import TRANSPORT_ITEMS, VIEW_ITEMS
from .common import _IMPL_ITEMS, _SCOPE_ITEMS, _active_material, _implementation, _progress

# ----------------------------------------------------------------------------------------
# Materials


def _assign(obj, mat) -> None:
    if obj is None or not hasattr(obj.data, "materials"):
        return
    if len(obj.material_slots) == 0:
        obj.data.materials.append(mat)
    else:
        obj.material_slots[obj.active_material_index].material = mat


class CTLAB_OT_new_material(bpy.types.Operator):
    """Create a Cook-Torrance material, assign it to the active object's active slot, and
    light it from the scene's Sun and world"""

    bl_idname = "ctlab.new_material"
    bl_label = "New Cook-Torrance Material"
    bl_options = {'REGISTER', 'UNDO'}

    implementation: EnumProperty(name="Implementation", items=_IMPL_ITEMS, default="PREFERENCES")
    light_transport: EnumProperty(
        name="Light Transport", items=TRANSPORT_ITEMS, default=DEFAULT_TRANSPORT[ARTIST]
    )

    def execute(self, context):
        impl = _implementation(self.implementation)
        mat = bpy.data.materials.new("Cook-Torrance")
        try:
            from ...blender.compat import use_nodes

            use_nodes(mat)
            tree = mat.node_tree
            tree.nodes.clear()
            with _progress(
                context,
                "Compiling the Cook-Torrance OSL shader..."
                if impl == "osl"
                else "Building the Cook-Torrance node group...",
            ):
                node = model_node.new_node(tree, impl)
            model_node.connect_output(tree, node)
            model_node.link_geometry_normal(tree, node)
            model_node.set_defaults(node, ARTIST, light_transport=self.light_transport)
            mat.cycles.emission_sampling = 'NONE'
            with _progress(context):
                light_sync.sync_material(mat, context.scene)
        except UserError as exc:
            bpy.data.materials.remove(mat)
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        _assign(context.object, mat)
        self.report(
            {'INFO'},
            f"New {IMPLEMENTATION_LABELS[impl][0]} material {mat.name!r}"
            + _osl_note(context.scene, impl == "osl"),
        )
        return {'FINISHED'}


def _tree_for_adding(context):
    space = getattr(context, "space_data", None)
    tree = getattr(space, "edit_tree", None)
    if tree is not None:
        return tree if tree.bl_idname == "ShaderNodeTree" else None
    mat = _active_material(context)
    return mat.node_tree if mat is not None else None


class CTLAB_OT_add_node_group(bpy.types.Operator):
    """Add the Cook-Torrance Lab node group (the model as shader nodes) to the node tree"""

    bl_idname = "ctlab.add_node_group"
    bl_label = "Cook-Torrance Lab"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return _tree_for_adding(context) is not None

    def execute(self, context):
        tree = _tree_for_adding(context)
        node = model_node.new_node(tree, "nodes")
        model_node.set_defaults(node, ARTIST)  # an artist's material
        space = getattr(context, "space_data", None)
        if hasattr(space, "cursor_location"):
            node.location = space.cursor_location
        for other in tree.nodes:
            other.select = False
        node.select = True
        tree.nodes.active = node
        mat = tree.id_data if isinstance(tree.id_data, bpy.types.Material) else None
        if mat is not None:
            try:
                light_sync.sync_material(mat, context.scene)
            except UserError as exc:
                self.report({'WARNING'}, f"added, but not lit: {exc}")
        return {'FINISHED'}


class CTLAB_OT_add_texture(bpy.types.Operator):
    """Wire an image texture into the active material's Cook-Torrance albedo, or a normal map
    into its normal"""

    bl_idname = "ctlab.add_texture"
    bl_label = "Add Texture"
    bl_options = {'REGISTER', 'UNDO'}

    slot: EnumProperty(
        name="Input",
        items=(
            ("albedo", "Albedo", "A colour texture"),
            ("normal", "Normal Map", "A tangent-space normal map"),
        ),
    )

    @classmethod
    def poll(cls, context):
        return model_node.find(_active_material(context)) is not None

    def execute(self, context):
        mat = _active_material(context)
        tree, node = mat.node_tree, model_node.find(mat)
        tex = tree.nodes.new("ShaderNodeTexImage")
        tex.location = (
            node.location.x - 600,
            node.location.y - (300 if self.slot == "normal" else 0),
        )
        if self.slot == "albedo":
            tree.links.new(tex.outputs["Color"], model_node.surface_input(node, "albedo"))
        else:
            nmap = tree.nodes.new("ShaderNodeNormalMap")
            nmap.location = (node.location.x - 300, node.location.y - 300)
            tree.links.new(tex.outputs["Color"], nmap.inputs["Color"])
            tree.links.new(nmap.outputs["Normal"], model_node.surface_input(node, "normal"))
            model_node.set_normal_derivatives(node)
        tree.nodes.active = tex
        return {'FINISHED'}


class CTLAB_OT_switch_implementation(bpy.types.Operator):
    """Carry the active material's Cook-Torrance node over to the other implementation,
    keeping its inputs, links and switches"""

    bl_idname = "ctlab.switch_implementation"
    bl_label = "Switch Implementation"
    bl_options = {'REGISTER', 'UNDO'}

    target: EnumProperty(name="Implementation", items=preferences.IMPLEMENTATION_ITEMS)

    @classmethod
    def poll(cls, context):
        return model_node.find(_active_material(context)) is not None

    def execute(self, context):
        mat = _active_material(context)
        node = model_node.find(mat)
        if model_node.implementation(node) == self.target:
            return {'CANCELLED'}
        was_reference = model_node.get_option(node, "ibl") == "reference"
        try:
            model_node.replace_node(mat.node_tree, node, self.target)
            light_sync.sync_material(mat, context.scene)
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        note = (
            " (reference indirect light became split-sum)"
            if was_reference and self.target == "nodes"
            else ""
        ) + _osl_note(context.scene, self.target == "osl")
        self.report({'INFO'}, f"{mat.name}: now the {IMPLEMENTATION_LABELS[self.target][0]}" + note)
        return {'FINISHED'}


def _osl_said(scene, turned_on: bool) -> str:
    """What a report adds for a material now carried by the OSL shader: that the scene's Open
    Shading Language was turned on, and what else keeps it from rendering."""
    reason = model_node.osl_unavailable_reason(scene)
    return ("; Open Shading Language turned on (Render Properties)" if turned_on else "") + (
        f"; it will not render here: {reason}" if reason else ""
    )


def _osl_note(scene, osl: bool) -> str:
    """For a material now carried by the OSL shader: turn on the scene's Open Shading
    Language (model_node.use_osl), and say so (_osl_said)."""
    return _osl_said(scene, model_node.use_osl(scene)) if osl else ""


def _scope_materials(context, scope: str) -> list:
    if scope == "ACTIVE":
        mat = _active_material(context)
        return [mat] if mat is not None else []
    seen = []
    for obj in context.selected_objects:
        for slot in obj.material_slots:
            if slot.material is not None and slot.material not in seen:
                seen.append(slot.material)
    return seen


class _Convert:
    bl_options = {'REGISTER', 'UNDO'}

    def convert(self, context, mat) -> list:
        raise NotImplementedError

    def note(self, context) -> str:
        """Said after the count of converted materials."""
        return ""

    def execute(self, context):
        mats = _scope_materials(context, self.scope)
        if not mats:
            self.report({'ERROR'}, "no material to convert: select an object with a material")
            return {'CANCELLED'}
        done, skipped = 0, []
        for mat in mats:
            try:
                notes = self.convert(context, mat)
            except UserError as exc:
                if self.scope == "ACTIVE":
                    self.report({'ERROR'}, str(exc))
                    return {'CANCELLED'}
                skipped.append(mat.name)
                continue
            done += 1
            if notes:
                self.report({'WARNING'}, f"{mat.name}: not carried over: {', '.join(notes)}")
        message = f"converted {done} material{'s' * (done != 1)}"
        if skipped:
            message += f"; skipped {', '.join(skipped)} (nothing to convert)"
        message += self.note(context)
        self.report({'INFO'}, message)
        return {'FINISHED'} if done else {'CANCELLED'}


class CTLAB_OT_convert_to_cook_torrance(_Convert, bpy.types.Operator):
    """Replace Principled BSDF by the Cook-Torrance model (Base Color -> albedo, Roughness ->
    1 - smoothness, Metallic, Normal; textures stay wired); reports what cannot be mapped"""

    bl_idname = "ctlab.convert_to_cook_torrance"
    bl_label = "Principled to Cook-Torrance"

    scope: EnumProperty(name="Materials", items=_SCOPE_ITEMS, default="ACTIVE")
    implementation: EnumProperty(name="Implementation", items=_IMPL_ITEMS, default="PREFERENCES")

    def convert(self, context, mat):
        from ...blender.convert import principled_to_model

        return principled_to_model(mat, context.scene, _implementation(self.implementation))

    def note(self, context) -> str:
        # principled_to_model turns OSL on (model_node.use_osl) where it was off
        if _implementation(self.implementation) != "osl":
            return ""
        scene = context.scene
        return _osl_said(scene, scene.cycles.shading_system and not self._osl_was_on)

    def execute(self, context):
        self._osl_was_on = bool(context.scene.cycles.shading_system)
        return super().execute(context)


class CTLAB_OT_convert_to_principled(_Convert, bpy.types.Operator):
    """Replace the Cook-Torrance model by a Principled BSDF (albedo -> Base Color, 1 -
    smoothness -> Roughness, Metallic, Normal; textures stay wired)"""

    bl_idname = "ctlab.convert_to_principled"
    bl_label = "Cook-Torrance to Principled"

    scope: EnumProperty(name="Materials", items=_SCOPE_ITEMS, default="ACTIVE")

    def convert(self, context, mat):
        from ...blender.convert import model_to_principled

        return model_to_principled(mat)


class CTLAB_OT_set_view_all(bpy.types.Operator):
    """Show the same view (the lit result or one term) on every Cook-Torrance material"""

    bl_idname = "ctlab.set_view_all"
    bl_label = "Set View on All"
    bl_options = {'REGISTER', 'UNDO'}

    view: EnumProperty(name="View", items=VIEW_ITEMS, default="full")

    def execute(self, context):
        count = 0
        for _mat, node in model_node.model_materials():
            model_node.set_option(node, "view", self.view)
            count += 1
        self.report({'INFO'}, f"view {self.view} on {count} material{'s' * (count != 1)}")
        return {'FINISHED'}
