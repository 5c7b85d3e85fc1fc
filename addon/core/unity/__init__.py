"""Unity's own material files, both ways, without bpy: ``read.py`` reads a ``.mat`` (Unity's
tagged, multi-document YAML, parsed with PyYAML) and the ``.meta`` files that give each
asset its guid, and says what a built-in Standard (metallic) material means for the model
(``Surface``); ``mat.py`` writes a Cook-Torrance material of the export
(``core.export.network.Material``) as a Standard ``.mat`` with its ``.meta`` files and the
packed metallic-gloss map (``unity_outputs``). docs/usage.md, "To and from Unity", is the
mapping table."""
