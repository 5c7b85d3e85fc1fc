"""The add-on's operators. Each validates before it changes anything, reports a UserError as
an ERROR (headless: bpy.ops raises RuntimeError with the message) and changes only what its
description says; the ones that edit a user's data are undoable."""

from __future__ import annotations

import math
from pathlib import Path

import bpy
from mathutils import Vector
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       IntProperty, StringProperty)

from . import preferences
from .properties import DIFFUSE_ITEMS, ENERGY_ITEMS, G_ITEMS, TRANSPORT_ITEMS, VIEW_ITEMS
from ..blender import light_sync, model_node
from ..blender.drivers import world_nodes
from ..blender.scene_builder import build_matrix
from ..core.errors import UserError
from ..core.paths import clean
from ..core.model import IBL_LABELS, IBL_MODES, MATRIX_ALBEDO, ModelOptions
from ..core.settings import MAX_GRID, SHADERS, MatrixSettings

_DEFAULTS = MatrixSettings()
_IBL_ITEMS = tuple((m, *IBL_LABELS[m]) for m in IBL_MODES)
_SHADER_LABELS = {"osl": ("Cook-Torrance (OSL)", "The OSL shader (Cycles on the CPU)"),
                  "nodes": ("Cook-Torrance (Node Group)", "The node group (Cycles and EEVEE)"),
                  "principled": ("Principled BSDF", "Blender's Principled BSDF, the reference")}
_SHADER_ITEMS = tuple((s, *_SHADER_LABELS[s]) for s in SHADERS)
_IMPL_ITEMS = (("PREFERENCES", "Preferences' Default", "The add-on preferences' implementation"),
               ) + preferences.IMPLEMENTATION_ITEMS
_SCOPE_ITEMS = (("ACTIVE", "Active Material", "The active object's active material"),
                ("SELECTED", "Selected Objects", "Every material of the selected objects"))


class _progress:
    """The window manager's progress indicator (a no-op without a window), as a
    ``progress(fraction, message)`` callable."""

    def __init__(self, context, status: str = ""):
        self.wm = context.window_manager if context.window else None
        self.workspace = getattr(context, "workspace", None) if context.window else None
        self.status = status

    def __enter__(self):
        if self.wm is not None:
            self.wm.progress_begin(0, 100)
        if self.status:
            print(f"Cook-Torrance Lab: {self.status}", flush=True)
            if self.workspace is not None:
                self.workspace.status_text_set(self.status)
                try:                                # drawn now, before the work blocks
                    bpy.ops.wm.redraw_timer(type='DRAW_WIN_SWAP', iterations=1)
                except RuntimeError:                # no window to draw (background)
                    pass
        return self

    def __call__(self, fraction, message):
        if self.wm is not None:
            self.wm.progress_update(int(100 * fraction))

    def __exit__(self, *exc):
        if self.wm is not None:
            self.wm.progress_end()
        if self.status and self.workspace is not None:
            self.workspace.status_text_set(None)


def _implementation(choice: str) -> str:
    return preferences.get().implementation if choice == "PREFERENCES" else choice


def _active_material(context):
    mat = getattr(context, "material", None)
    if mat is None and context.object is not None:
        mat = context.object.active_material
    return mat


def _default_hdri() -> str:
    return bpy.path.abspath(preferences.get().hdri) if preferences.get().hdri else ""


# ----------------------------------------------------------------------------------------
# The sphere matrix and the environment bake

class CTLAB_OT_build_sphere_matrix(bpy.types.Operator):
    """Build a metallic x smoothness matrix of spheres lit by an HDRI and a Sun.
    Rebuilding replaces only the objects this operator made"""
    bl_idname = "ctlab.build_sphere_matrix"
    bl_label = "Build Sphere Matrix"
    bl_options = {'REGISTER', 'UNDO'}

    rows: IntProperty(name="Rows (smoothness)", default=_DEFAULTS.rows, min=1, max=MAX_GRID)
    cols: IntProperty(name="Columns (metallic)", default=_DEFAULTS.cols, min=1, max=MAX_GRID)
    spacing: FloatProperty(name="Spacing", default=_DEFAULTS.spacing, min=0.85, max=10,
                           unit='LENGTH', description="Distance between sphere centres")
    albedo: FloatVectorProperty(name="Albedo", subtype='COLOR', size=3, min=0, max=1,
                                default=MATRIX_ALBEDO)
    hdri: StringProperty(name="HDRI", subtype='FILE_PATH', default="",
                         description="Equirectangular HDRI; empty: the preferences' default "
                                     "HDRI, else Blender's bundled forest.exr")
    hdri_strength: FloatProperty(name="HDRI Strength", default=1.0, min=0, soft_max=10)
    hdri_rotation: FloatProperty(name="HDRI Rotation", default=0.0, subtype='ANGLE',
                                 description="Rotation of the world about Z")
    sun_direction: FloatVectorProperty(name="Sun Direction", subtype='DIRECTION', size=3,
                                       default=_DEFAULTS.sun_to_light,
                                       description="Direction toward the Sun")
    sun_strength: FloatProperty(name="Sun Strength", default=_DEFAULTS.sun_strength, min=0,
                                soft_max=20, description="Sun irradiance (W/m²)")
    shader: EnumProperty(name="Shader", default="osl", items=_SHADER_ITEMS)
    view: EnumProperty(name="View", default="full", items=VIEW_ITEMS)
    ibl: EnumProperty(name="Indirect Light", default=IBL_MODES[0], items=_IBL_ITEMS)
    resolution: IntProperty(name="Resolution", default=512, min=16, max=4096, subtype='PIXEL')

    def execute(self, context):
        ibl = "split_sum" if self.shader == "nodes" and self.ibl == "reference" else self.ibl
        try:
            settings = MatrixSettings(
                rows=self.rows, cols=self.cols, spacing=self.spacing, albedo=tuple(self.albedo),
                hdri=bpy.path.abspath(self.hdri) if self.hdri else _default_hdri(),
                hdri_strength=self.hdri_strength,
                hdri_rotation=math.degrees(self.hdri_rotation),
                sun_to_light=tuple(self.sun_direction), sun_strength=self.sun_strength,
                shader=self.shader, width=self.resolution, height=self.resolution,
                model=ModelOptions(view=self.view, ibl=ibl))
            with _progress(context) as progress:
                build_matrix(context.scene, settings, progress)
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        scene = context.scene
        scene.render.engine = 'CYCLES'
        scene.cycles.shading_system = (self.shader == "osl")
        self.report({'INFO'}, f"Built a {self.rows}x{self.cols} sphere matrix")
        return {'FINISHED'}

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)


class CTLAB_OT_bake_environment(bpy.types.Operator):
    """Bake the split-sum files of an HDRI (pre-filtered specular levels, irradiance and the
    DFG tables) into the cache, once per image content"""
    bl_idname = "ctlab.bake_environment"
    bl_label = "Bake Environment"
    bl_options = {'REGISTER'}

    filepath: StringProperty(name="HDRI", subtype='FILE_PATH', default="",
                             description="Equirectangular HDRI; empty: the world's Environment "
                                         "Texture, else Blender's bundled forest.exr")

    def execute(self, context):
        from ..core import ibl_bake
        from ..blender.paths import bundled_hdri
        path = (bpy.path.abspath(self.filepath) if self.filepath
                else light_sync.world_hdri_path(context.scene)) or _default_hdri() \
            or str(bundled_hdri("forest"))
        warnings = []
        try:
            with _progress(context) as progress:
                folder = ibl_bake.bake(Path(path), progress, warnings.append)
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        for message in warnings:
            self.report({'WARNING'}, message)
        context.scene["ctlab_ibl_bake"] = str(folder)
        self.report({'INFO'}, f"Baked {Path(path).name}: {folder}")
        return {'FINISHED'}


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

    implementation: EnumProperty(name="Implementation", items=_IMPL_ITEMS,
                                 default="PREFERENCES")
    light_transport: EnumProperty(name="Light Transport", items=TRANSPORT_ITEMS,
                                  default="scene")

    def execute(self, context):
        impl = _implementation(self.implementation)
        mat = bpy.data.materials.new("Cook-Torrance")
        try:
            from ..blender.compat import use_nodes
            use_nodes(mat)
            tree = mat.node_tree
            tree.nodes.clear()
            with _progress(context, "Compiling the Cook-Torrance OSL shader..."
                           if impl == "osl" else "Building the Cook-Torrance node group..."):
                node = model_node.new_node(tree, impl)
            model_node.connect_output(tree, node)
            model_node.link_geometry_normal(tree, node)
            if impl == "nodes":
                model_node.set_option(node, "ibl", "split_sum")
            model_node.set_option(node, "light_transport", self.light_transport)
            mat.cycles.emission_sampling = 'NONE'
            with _progress(context):
                light_sync.sync_material(mat, context.scene)
        except UserError as exc:
            bpy.data.materials.remove(mat)
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        _assign(context.object, mat)
        self.report({'INFO'}, f"New {model_node.IMPLEMENTATION_LABELS[impl]} material "
                              f"{mat.name!r}")
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
        model_node.set_option(node, "ibl", "split_sum")
        model_node.set_option(node, "light_transport", "scene")    # an artist's material
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

    slot: EnumProperty(name="Input", items=(("albedo", "Albedo", "A colour texture"),
                                            ("normal", "Normal Map", "A tangent-space normal map")))

    @classmethod
    def poll(cls, context):
        return model_node.find(_active_material(context)) is not None

    def execute(self, context):
        mat = _active_material(context)
        tree, node = mat.node_tree, model_node.find(mat)
        tex = tree.nodes.new("ShaderNodeTexImage")
        tex.location = (node.location.x - 600, node.location.y - (300 if self.slot == "normal" else 0))
        if self.slot == "albedo":
            tree.links.new(tex.outputs["Color"], model_node.surface_input(node, "albedo"))
        else:
            nmap = tree.nodes.new("ShaderNodeNormalMap")
            nmap.location = (node.location.x - 300, node.location.y - 300)
            tree.links.new(tex.outputs["Color"], nmap.inputs["Color"])
            tree.links.new(nmap.outputs["Normal"], model_node.surface_input(node, "normal"))
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
        if self.target == "osl":
            context.scene.cycles.shading_system = True
        note = " (reference indirect light became split-sum)" if was_reference and \
            self.target == "nodes" else ""
        self.report({'INFO'}, f"{mat.name}: now the {model_node.IMPLEMENTATION_LABELS[self.target]}"
                              + note)
        return {'FINISHED'}


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
        self.report({'INFO'}, message)
        return {'FINISHED'} if done else {'CANCELLED'}


class CTLAB_OT_convert_to_cook_torrance(_Convert, bpy.types.Operator):
    """Replace Principled BSDF by the Cook-Torrance model (Base Color -> albedo, Roughness ->
    1 - smoothness, Metallic, Normal; textures stay wired); reports what cannot be mapped"""
    bl_idname = "ctlab.convert_to_cook_torrance"
    bl_label = "Principled to Cook-Torrance"

    scope: EnumProperty(name="Materials", items=_SCOPE_ITEMS, default="ACTIVE")
    implementation: EnumProperty(name="Implementation", items=_IMPL_ITEMS,
                                 default="PREFERENCES")

    def convert(self, context, mat):
        from ..blender.convert import principled_to_model
        return principled_to_model(mat, context.scene, _implementation(self.implementation))


class CTLAB_OT_convert_to_principled(_Convert, bpy.types.Operator):
    """Replace the Cook-Torrance model by a Principled BSDF (albedo -> Base Color, 1 -
    smoothness -> Roughness, Metallic, Normal; textures stay wired)"""
    bl_idname = "ctlab.convert_to_principled"
    bl_label = "Cook-Torrance to Principled"

    scope: EnumProperty(name="Materials", items=_SCOPE_ITEMS, default="ACTIVE")

    def convert(self, context, mat):
        from ..blender.convert import model_to_principled
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


def sync_summary(scene, count: int) -> str:
    """What light sync did, in one line: the key Sun (if any), the lights in slots, the world."""
    from ..blender import scene_lights
    sun = light_sync.key_sun(scene)
    used, unused = scene_lights.scene_lights(scene, exclude=sun)
    lights = [f"the key Sun {sun.name}"] if sun else ["no key Sun"]
    if used:
        lights.append(f"{len(used)} light{'s' * (len(used) != 1)} in slots "
                      f"({', '.join(o.name for o in used)})")
    if unused:
        lights.append(f"{len(unused)} left over")
    return f"{count} material{'s' * (count != 1)} follow {'; '.join(lights)} and the world"


class CTLAB_OT_sync_lighting(bpy.types.Operator):
    """Drive every Cook-Torrance material's key light from the key Sun and its HDRI from the
    world (done by itself when they change; this redoes it now)"""
    bl_idname = "ctlab.sync_lighting"
    bl_label = "Sync Lighting"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        count = 0
        env = light_sync.Environment(context.scene)
        try:
            for mat, _node in light_sync.user_materials():
                light_sync.sync_material(mat, context.scene, env=env)
                count += 1
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        self.report({'INFO'}, sync_summary(context.scene, count))
        return {'FINISHED'}


# ----------------------------------------------------------------------------------------
# The comparison job in the background

JOBS: dict = {}                  # "comparison", "plot" -> background_job.Job
PLOT_IMAGE = "Cook-Torrance BRDF Plot"


def _job_tick():
    """Timer: copy each job's progress into the window manager and redraw; when a job ends,
    act on it once (open the comparison's report, load the BRDF plot into an image). Stops
    when no job runs."""
    wm = bpy.context.window_manager
    running = False
    for kind, job in list(JOBS.items()):
        state = job.poll()
        if kind == "comparison":
            wm.ctlab_job_progress, wm.ctlab_job_message, wm.ctlab_job_state = \
                job.fraction, job.message, state
        else:
            wm.ctlab_plot_message, wm.ctlab_plot_state = job.message, state
        if state in ("running", "cancelling"):
            running = True
        elif not getattr(job, "handled", False):
            job.handled = True
            if getattr(job, "staging", None) is not None:       # the scene job's file copy
                import shutil
                shutil.rmtree(job.staging, ignore_errors=True)
            if kind == "comparison" and state == "done" and job.open_report and \
                    not bpy.app.background:
                bpy.ops.wm.url_open(url=job.report.as_uri())
            elif kind == "plot" and state == "done":
                try:
                    show_plot(job.out_dir / "plot.png")
                except (RuntimeError, OSError) as exc:     # the file went away meanwhile
                    job.state = "failed"
                    wm.ctlab_plot_message, wm.ctlab_plot_state = \
                        f"cannot open plot.png: {exc}", "failed"
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type in ('VIEW_3D', 'PROPERTIES', 'IMAGE_EDITOR'):
                area.tag_redraw()
    return 0.5 if running else None


def _start_tick() -> None:
    if not bpy.app.timers.is_registered(_job_tick):     # one timer, however many jobs
        bpy.app.timers.register(_job_tick, first_interval=0.5)


def show_plot(path: Path) -> bpy.types.Image:
    """The plot's PNG as the image PLOT_IMAGE (reloaded when it exists), shown in every open
    Image Editor."""
    if not Path(path).is_file():
        raise OSError(f"{path} does not exist")
    image = bpy.data.images.get(PLOT_IMAGE)
    if image is None:
        image = bpy.data.images.load(str(path))
        image.name = PLOT_IMAGE
    else:
        if image.packed_file is not None:          # packed by the user: show the new file
            image.unpack(method='REMOVE')
        image.filepath = str(path)
        image.reload()
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == 'IMAGE_EDITOR':
                area.spaces.active.image = image
    return image


def _comparison_running(op) -> bool:
    """Whether a comparison job runs (reported as the operator's error)."""
    running = JOBS.get("comparison")
    if running is not None and running.poll() in ("running", "cancelling"):
        op.report({'ERROR'}, "a comparison is already running; cancel it first")
        return True
    return False


def _start_comparison(context, job) -> None:
    """Follow a started comparison job in the sidebar (the timer polls it)."""
    JOBS["comparison"] = job
    wm = context.window_manager
    wm.ctlab_job_state, wm.ctlab_job_message, wm.ctlab_job_progress = "running", "starting", 0.0
    _start_tick()


def default_comparison_folder() -> str:
    if bpy.data.filepath:
        return "//ctlab_comparison"
    from ..core.cache import cache_dir
    return str(cache_dir().parent / "comparison")


class CTLAB_OT_render_comparison(bpy.types.Operator):
    """Render the sphere matrix with Cook-Torrance and Principled BSDF in a background
    process and compare them cell by cell; the report opens when done"""
    bl_idname = "ctlab.render_comparison"
    bl_label = "Render Comparison"
    bl_options = {'REGISTER'}

    directory: StringProperty(name="Output Folder", subtype='DIR_PATH', default="",
                              description="Empty: //ctlab_comparison next to the .blend, or "
                                          "the add-on's user folder")
    rows: IntProperty(name="Rows", default=5, min=1, max=MAX_GRID)
    cols: IntProperty(name="Columns", default=5, min=1, max=MAX_GRID)
    size: IntProperty(name="Size", default=384, min=16, max=4096, subtype='PIXEL')
    samples: IntProperty(name="Samples", default=0, min=0, max=65536,
                         description="0: the preferences' default samples")
    open_report: BoolProperty(name="Open Report", default=True)

    def execute(self, context):
        from ..core.files import check_writable
        from ..jobs import background_job
        from ..jobs.cli import argv as job_argv
        if _comparison_running(self):
            return {'CANCELLED'}
        out = Path(bpy.path.abspath(self.directory or default_comparison_folder()))
        scene = context.scene
        hdri = light_sync.world_hdri_path(scene) or _default_hdri()
        values = dict(grid=f"{self.rows}x{self.cols}", size=self.size,
                      samples=self.samples or preferences.get().samples)
        if hdri:
            values["hdri"] = hdri
        background, mapping = world_nodes(scene.world)
        if background is not None and hdri:
            values["hdri_strength"] = background.inputs['Strength'].default_value
        if mapping is not None and hdri:
            values["hdri_rotation"] = math.degrees(mapping.inputs['Rotation'].default_value[2])
        sun = light_sync.key_sun(scene)
        if sun is not None:
            values["sun_dir"] = tuple(sun.matrix_world.to_quaternion() @ Vector((0.0, 0.0, 1.0)))
            values["sun_strength"] = sun.data.energy
        argv = job_argv("matrix", "--out", out, **values)
        try:
            clean(str(out), "output folder", output=True)    # the one path gate, first
            check_writable(out)
            if hdri:
                from ..core.hdri import load_hdri
                load_hdri(Path(hdri))
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        job = background_job.Job(argv, out)
        job.open_report = self.open_report
        _start_comparison(context, job)
        self.report({'INFO'}, f"comparison started in the background -> {out}")
        return {'FINISHED'}

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)


# "each material's own", before a switch's values (the scene comparison's overrides)
_KEEP = (("MATERIAL", "Each Material's", "Each model material keeps its own setting"),)


class CTLAB_OT_scene_comparison(bpy.types.Operator):
    """Render this scene through its camera twice in a background process, with its
    Cook-Torrance materials and with each converted to Principled BSDF, and compare them
    material by material (ctlab scene); the report opens when done"""
    bl_idname = "ctlab.scene_comparison"
    bl_label = "Compare Scene with Principled"
    bl_options = {'REGISTER'}

    directory: StringProperty(name="Output Folder", subtype='DIR_PATH', default="",
                              description="Empty: //ctlab_scene next to the .blend, or the "
                                          "add-on's user folder")
    size: IntProperty(name="Size", default=384, min=16, max=4096, subtype='PIXEL',
                      description="The longer image side (the camera's aspect is kept)")
    samples: IntProperty(name="Samples", default=0, min=0, max=65536,
                         description="0: the preferences' default samples")
    light_transport: EnumProperty(name="Light Transport", items=TRANSPORT_ITEMS,
                                  default="scene")
    convert: BoolProperty(name="Convert Principled", default=False,
                          description="The other way: the scene's Principled materials "
                                      "converted to the model, the originals as the reference")
    shader: EnumProperty(name="Implementation", items=_KEEP + preferences.IMPLEMENTATION_ITEMS,
                         default="MATERIAL")
    g_model: EnumProperty(name="G", items=_KEEP + G_ITEMS, default="MATERIAL")
    diffuse_model: EnumProperty(name="Diffuse", items=_KEEP + DIFFUSE_ITEMS, default="MATERIAL")
    energy: EnumProperty(name="Energy", items=_KEEP + ENERGY_ITEMS, default="MATERIAL")
    camera: StringProperty(name="Camera", default="",
                           description="A camera object of the scene (empty: the scene's)")
    open_report: BoolProperty(name="Open Report", default=True)

    def command(self, blend: Path, out: Path) -> list:
        """The ``ctlab scene`` command line of these settings."""
        argv = ["scene", str(blend), "--out", str(out), "--size", str(self.size),
                "--samples", str(self.samples or preferences.get().samples),
                "--light-transport", self.light_transport]
        if self.convert:
            argv.append("--convert")
        for flag, value in (("--shader", self.shader), ("--g", self.g_model),
                            ("--diffuse", self.diffuse_model), ("--energy", self.energy),
                            ("--camera", self.camera)):
            if value and value != "MATERIAL":
                argv.append(f"{flag}={value}")
        return argv

    def execute(self, context):
        import shutil
        import tempfile
        from ..core.files import check_writable
        from ..jobs import background_job
        if _comparison_running(self):
            return {'CANCELLED'}
        camera = bpy.data.objects.get(self.camera) if self.camera else context.scene.camera
        if camera is None or camera.type != 'CAMERA':
            self.report({'ERROR'}, f"no camera named {self.camera!r} in this file" if
                        self.camera else "the scene has no camera; add one to compare the scene")
            return {'CANCELLED'}
        folder = self.directory or ("//ctlab_scene" if bpy.data.filepath else
                                    str(Path(default_comparison_folder()).parent / "scene"))
        out = Path(bpy.path.abspath(folder))
        try:
            clean(str(out), "output folder", output=True)    # the one path gate, first
            check_writable(out)
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        # the job reads a copy of the file as it is now (the open file is never written)
        staging = Path(tempfile.mkdtemp(prefix="ctlab-scene-"))
        copy = staging / "scene.blend"
        try:
            # relative paths are remapped to the copy's folder, so they still resolve
            bpy.ops.wm.save_as_mainfile(filepath=str(copy), copy=True, relative_remap=True)
        except RuntimeError as exc:
            shutil.rmtree(staging, ignore_errors=True)
            self.report({'ERROR'}, f"cannot copy the scene for the comparison: {exc}")
            return {'CANCELLED'}
        try:
            job = background_job.Job(self.command(copy, out), out)
        except OSError as exc:
            shutil.rmtree(staging, ignore_errors=True)
            self.report({'ERROR'}, f"cannot start the scene comparison: {exc}")
            return {'CANCELLED'}
        job.open_report = self.open_report
        job.staging = staging                       # removed when the job ends
        _start_comparison(context, job)
        self.report({'INFO'}, f"scene comparison started in the background -> {out}")
        return {'FINISHED'}

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)


class CTLAB_OT_cancel_comparison(bpy.types.Operator):
    """Stop the background comparison after its current render; finished renders are kept"""
    bl_idname = "ctlab.cancel_comparison"
    bl_label = "Cancel Comparison"
    bl_options = {'REGISTER'}

    @classmethod
    def poll(cls, context):
        job = JOBS.get("comparison")
        return job is not None and job.state == "running"

    def execute(self, context):
        JOBS["comparison"].cancel()
        context.window_manager.ctlab_job_state = "cancelling"
        return {'FINISHED'}


# ----------------------------------------------------------------------------------------
# The BRDF plot of a material, in the background

def default_plot_folder() -> str:
    """The add-on's user folder (the extension's, or beside the cache): never the install
    folder."""
    from ..core.cache import cache_dir
    return str(cache_dir().parent / "cook-torrance-lab-brdf-plot")


def plot_command(node, out: Path, compare_g: bool = False) -> tuple:
    """``ctlab plot`` for a model node's values (surface inputs as their sockets hold them,
    clamped to the model's range as the model clamps them) and switches; with the notes on
    inputs a texture or another node drives (plotted at the socket's own value)."""
    from ..core.model import G_MODELS, clamp01
    notes, values = [], {}
    for key in ("albedo", "metallic", "smoothness"):
        sock = model_node.surface_input(node, key)
        if sock.is_linked:
            notes.append(f"{key} is linked to {sock.links[0].from_node.name}; plotted at the "
                         "socket's value")
        value = sock.default_value
        values[key] = [clamp01(x) for x in value[:3]] if key == "albedo" else clamp01(value)
    options = {k: model_node.get_option(node, k) for k in ("g_model", "diffuse_model",
                                                            "units", "energy")}
    argv = ["plot", f"--out={out}", f"--metallic={values['metallic']:.9g}",
            f"--smoothness={values['smoothness']:.9g}",
            "--albedo=" + ",".join(f"{x:.9g}" for x in values["albedo"]),
            f"--g={options['g_model']}", f"--diffuse={options['diffuse_model']}",
            f"--units={options['units']}", f"--energy={options['energy']}",
            f"--shader={model_node.implementation(node)}"]
    if compare_g:
        argv.append("--compare=" + ",".join(f"g={g}" for g in G_MODELS
                                            if g != options["g_model"]))
    return argv, notes


class CTLAB_OT_brdf_plot(bpy.types.Operator):
    """Plot the active material's BRDF from the model's own code (in a background process):
    the θh × θd slice, the lobes and the directional albedo, shown as the image
    "Cook-Torrance BRDF Plot" in the Image Editor"""
    bl_idname = "ctlab.brdf_plot"
    bl_label = "BRDF Plot"
    bl_options = {'REGISTER'}

    directory: StringProperty(name="Output Folder", subtype='DIR_PATH', default="",
                              description="Empty: the add-on's user folder")
    compare_g: BoolProperty(name="Compare G Models", default=False,
                            description="Overlay the other G models' lobes and slices")

    @classmethod
    def poll(cls, context):
        return model_node.find(_active_material(context)) is not None

    def execute(self, context):
        from ..core.files import check_writable
        from ..jobs import background_job
        running = JOBS.get("plot")
        if running is not None and running.poll() == "running":
            self.report({'ERROR'}, "a BRDF plot is already being made; wait for it")
            return {'CANCELLED'}
        node = model_node.find(_active_material(context))
        out = Path(bpy.path.abspath(self.directory or default_plot_folder()))
        try:
            clean(str(out), "output folder", output=True)    # the one path gate, first
            check_writable(out)
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        argv, notes = plot_command(node, out, self.compare_g)
        for note in notes:
            self.report({'WARNING'}, note)
        JOBS["plot"] = background_job.Job(argv, out)
        context.window_manager.ctlab_plot_state = "running"
        context.window_manager.ctlab_plot_message = "starting"
        _start_tick()
        self.report({'INFO'}, f"BRDF plot started -> {out}; it opens as the image "
                              f"'{PLOT_IMAGE}'")
        return {'FINISHED'}


def stop_jobs() -> None:
    """On unregister: no child process or timer may outlive the add-on."""
    for kind in list(JOBS):
        job = JOBS.pop(kind)
        if job.process.poll() is None:
            job.process.kill()
            job.process.wait()
    # a timer left registered at exit hangs Blender's shutdown (measured: a second job
    # registered a second timer and the process never exited)
    while bpy.app.timers.is_registered(_job_tick):
        bpy.app.timers.unregister(_job_tick)


CLASSES = (CTLAB_OT_build_sphere_matrix, CTLAB_OT_bake_environment, CTLAB_OT_new_material,
           CTLAB_OT_add_node_group, CTLAB_OT_add_texture, CTLAB_OT_switch_implementation,
           CTLAB_OT_convert_to_cook_torrance, CTLAB_OT_convert_to_principled,
           CTLAB_OT_set_view_all, CTLAB_OT_sync_lighting, CTLAB_OT_render_comparison,
           CTLAB_OT_scene_comparison,
           CTLAB_OT_cancel_comparison, CTLAB_OT_brdf_plot)
