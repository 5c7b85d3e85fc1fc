"""Cook-Torrance Lab's modules, in four layers that import only downward:

- ``core``: the model's interface and everything that needs no Blender (settings and their
  validation, HDRI and cache files, the split-sum bake, the importance tables, the
  comparison and the report); numpy and OpenImageIO only.
- ``blender``: the model in Blender (the OSL shader, the node group, the one model-node API,
  materials, the sphere-matrix scene, light sync, conversion, rendering, version differences).
- ``jobs``: the pipeline (render views, the matrix and parity jobs, progress and cancel), the
  command line, and the job run in a background process.
- ``ui``: what Blender's interface shows (operators, panels, properties, preferences) and
  registration (ui/register.py).
"""
