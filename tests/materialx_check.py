"""MaterialX's own checks of a written .mtlx, for the tests of both tiers: validate() against
its standard libraries and OSL from its OSL generator (PyPI materialx, in
scripts/requirements-*.txt), run in a child process that does not import bpy, since
Blender's bundled MaterialX (another version, without the OSL generator) may already be
loaded in the test process."""

import json
import os
import subprocess
import sys
import textwrap

MTLX = textwrap.dedent(r'''
    import json, sys
    import MaterialX as mx
    from MaterialX import PyMaterialXGenShader as gs, PyMaterialXGenOsl as go
    search = mx.getDefaultDataSearchPath()
    lib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), search, lib)
    include = search.find("libraries/stdlib/genosl/include")

    def inline(text, seen):
        """The generated OSL whole: its includes inlined once each (MaterialX's headers),
        '#pragma once' dropped (Blender 5.2's OSL compiler crashes on it)."""
        out = []
        for line in text.splitlines():
            s = line.strip()
            if s.startswith("#pragma once"):
                continue
            if s.startswith("#include"):
                name = s.split('"')[1]
                if name not in seen:
                    seen.add(name)
                    out.append(inline(open(include.asString() + "/" + name).read(), seen))
                continue
            out.append(line)
        return "\n".join(out)

    out = {}
    for path in sys.argv[1:]:
        doc = mx.createDocument()
        mx.readFromXmlFile(doc, path)
        doc.setDataLibrary(lib)
        ok, message = doc.validate()
        gen = go.OslShaderGenerator.create()
        ctx = gs.GenContext(gen)
        ctx.registerSourceCodeSearchPath(search)
        shader = next(n for n in doc.getNodes() if n.getType() == "surfaceshader")
        osl = gen.generate("mtlx_" + shader.getName(), shader, ctx).getSourceCode(gs.PIXEL_STAGE)
        osl = inline(osl, set())
        out[path] = {"valid": ok, "message": message, "osl": osl,
                     "version": mx.getVersionString()}
    print(json.dumps(out))
''')


def materialx_check(paths) -> dict:
    """{path: {"valid", "message", "osl", "version"}} for each .mtlx (the OSL whole: its
    includes inlined, '#pragma once' dropped)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    run = subprocess.run(
        [sys.executable, "-c", MTLX, *map(str, paths)],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    return json.loads(run.stdout)
