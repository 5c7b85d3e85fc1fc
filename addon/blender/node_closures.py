"""The node group's closure terms as Emission closures behind Mix Shader nodes, whose
zero-weight branches Cycles skips with every node that only they use (``closures``), and a
pre-filtered term as a chain of them (``chain``): the shader side of node_compiler's
expressions (blender/node_group.py calls them)."""

from __future__ import annotations

from ..core.errors import UserError
from ..core.ibl_bake import LEVEL_COUNT
from .node_compiler import CHAIN_INPUTS, Compiler


def closures(b: Compiler, views: dict, view_on: list, rest, frame: str = "views"):
    """The Emission output: the view's colour without its closure terms, plus each term as
    an Emission closure behind Mix Shader nodes, whose zero-weight branches Cycles skips with
    every node that only they use. The views are sums of terms, so a term enters each view
    that uses it once, with weight (View == k) (``view_on``; None: weight 1, for a sum that
    is not chosen by the View, the scene transport's correction).

    - ``gated(c, X)``: mix(nothing, X, c > 0), for a term that is zero where c <= 0 (the
      direct light where n.l <= 0).
    - ``prefiltered(x, dir, c)``: sum_k max(0, 1 - |x - k|) L_k(dir) c as a chain,
      M_6 = L_6 c, M_k = mix(L_k c, M_k+1, clamp(x - k, 0, 1)). For x in [j, j + 1] this is
      (1 - f) L_j c + f L_j+1 c, the same sum, and Cycles reads two levels, not seven.

    The closure terms are those the last emission-mode pass met (b.closure_terms), which
    this consumes."""
    b.current_frame = frame

    emit, mix = b.emission, b.mix_shader

    def weighted(colour, weight):
        return colour if weight is None else b.call("vec.SCALE", [colour, weight])

    total = emit(rest)
    terms, b.closure_terms = b.closure_terms, {}
    for name, (op, args) in terms.items():
        weight = None
        for k, (view, tree) in enumerate(views.items()):
            count = b.additive_count(tree, name)
            if count not in (0, 1):
                raise UserError(
                    f"node description: the view {view!r} must hold {name!r} at "
                    "most once, as a term of a sum (vec.ADD), since the group's "
                    "Emission output adds it as a closure"
                )
            if count and view_on is not None:
                on = view_on[k]
                weight = on if weight is None else b.call("math.ADD", [weight, on])
        if op == "gated":
            c, colour = args
            closure = mix(
                b.call("math.GREATER_THAN", [c, 0.0]), None, emit(weighted(colour, weight)), name
            )
        elif b.chain_group is not None:  # the chain below, as an instance of that group
            x, direction, factor = args
            node = b.new("ShaderNodeGroup")
            node.node_tree = b.chain_group
            node.label = name
            for sock, value in zip(CHAIN_INPUTS, (x, direction, weighted(factor, weight))):
                b.link(value, node.inputs[sock[0]])
            closure = node.outputs[0]
        else:
            x, direction, factor = args
            closure = chain(b, x, direction, weighted(factor, weight), name, emit, mix)
        add = b.new("ShaderNodeAddShader")
        b.link(total, add.inputs[0])
        b.link(closure, add.inputs[1])
        total = add.outputs["Shader"]
    return total


def chain(b: Compiler, x, direction, factor, name: str, emit, mix):
    """prefiltered(x, direction, factor) as a chain of Mix Shader nodes (``closures``)."""

    def level(k):
        return emit(b.call("vec.MULTIPLY", [b.environment(f"specular_{k}", direction), factor]))

    closure = level(LEVEL_COUNT - 1)
    for k in range(LEVEL_COUNT - 2, -1, -1):
        closure = mix(
            b.call("math.SUBTRACT!", [x, float(k)]),
            level(k),
            closure,
            f"{name}: levels {k}-{LEVEL_COUNT - 1}",
        )
    return closure
