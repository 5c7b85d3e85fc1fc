"""The model outside Blender (``ctlab export``): the MaterialX network as data
(network.py), written as MaterialX (materialx.py), USD (usd.py) and glTF (gltf.py)."""
