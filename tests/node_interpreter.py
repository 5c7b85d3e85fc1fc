"""A small interpreter of the node group's Math and Vector Math nodes (for the tests of the
scene transport's structure, tests/slow/test_scene_transport_nodes.py): ``evaluate`` follows
a socket's links back through the group, computing each node's operation in numpy from the
group's input values (``group_inputs``) and the path's (a Light Path node: a camera hit
unless told), so that a formula of the description can be checked
exactly without a render."""

import math

import numpy as np

MATH = {
    "ADD": lambda a, b: a + b,
    "SUBTRACT": lambda a, b: a - b,
    "MULTIPLY": lambda a, b: a * b,
    "DIVIDE": lambda a, b: a / b if b else 0.0,
    "MAXIMUM": max,
    "MINIMUM": min,
    "SQRT": lambda a, b: math.sqrt(a) if a > 0 else 0.0,
    "GREATER_THAN": lambda a, b: float(a > b),
    "LESS_THAN": lambda a, b: float(a < b),
}
VECTOR_MATH = {
    "ADD": np.add,
    "SUBTRACT": np.subtract,
    "MULTIPLY": np.multiply,
    "MINIMUM": np.minimum,
    "MAXIMUM": np.maximum,
}


# The Light Path node's outputs at a camera ray's hit, unless ``inputs`` says ("path:NAME")
LIGHT_PATH = {"Ray Depth": 0.0, "Is Camera Ray": 1.0}


def input_value(sock, inputs):
    if sock.is_linked:
        return evaluate(sock.links[0].from_socket, inputs)
    v = sock.default_value
    return np.array(v[:3], dtype=np.float64) if hasattr(v, "__len__") else float(v)


def evaluate(sock, inputs):
    """The value of an output socket built from the group's inputs by Math and Vector Math
    nodes, per Blender's documented operations (``inputs``: group input name -> value)."""
    node = sock.node
    if node.bl_idname == "NodeGroupInput":
        return inputs[sock.name]
    if node.bl_idname == "ShaderNodeLightPath":  # the path at the hit: inputs["path:Ray Depth"]
        return float(inputs.get(f"path:{sock.name}", LIGHT_PATH[sock.name]))
    if node.bl_idname == "ShaderNodeMath":
        a, b, c = (input_value(s, inputs) for s in node.inputs[:3])
        if node.operation == "COMPARE":
            out = float(abs(a - b) <= max(c, 1e-5))
        else:
            out = MATH[node.operation](a, b)
        return min(max(out, 0.0), 1.0) if node.use_clamp else out
    if node.bl_idname == "ShaderNodeVectorMath":
        a = input_value(node.inputs[0], inputs)
        if node.operation == "SCALE":
            return a * input_value(node.inputs["Scale"], inputs)
        return VECTOR_MATH[node.operation](a, input_value(node.inputs[1], inputs))
    raise AssertionError(f"cannot evaluate {node.bl_idname} {node.name} ({node.label})")


def source_of(sock):
    assert sock.is_linked, f"{sock.node.name}.{sock.name} is not linked"
    return sock.links[0].from_socket


def group_inputs(**values):
    from addon.core.model import GROUP_INPUTS

    out = {}
    for i in GROUP_INPUTS:
        v = values.get(i.group, i.default)
        out[i.group] = np.array(v[:3], dtype=np.float64) if isinstance(v, tuple) else float(v)
    return out
