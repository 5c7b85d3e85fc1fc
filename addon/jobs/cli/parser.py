"""The parser, assembled from the commands (each command's module: its options and what runs
it), and the command lines written from the same table (``argv``, for the add-on's
background jobs), so that a command line a caller builds cannot drift from what the parser
reads."""

from __future__ import annotations

import argparse
import re

from .bake import COMMAND as BAKE
from .compare import COMMAND as COMPARE
from .export import COMMAND as EXPORT
from .matrix import COMMAND as MATRIX
from .plot import COMMAND as PLOT
from .render import COMMAND as RENDER
from .scene import COMMAND as SCENE
from .tasks import COMMANDS as TASKS
from .unity import COMMAND as IMPORT_UNITY
from ...core.errors import UserError

# in the order `ctlab --help` lists them
COMMANDS = {
    c.name: c for c in (RENDER, COMPARE, BAKE, MATRIX, *TASKS, PLOT, SCENE, EXPORT, IMPORT_UNITY)
}

# the options that take a value, of every command
VALUE_FLAGS = frozenset(
    o.flag for c in COMMANDS.values() for o in c.options if o.takes_value and not o.positional
)


class Parser(argparse.ArgumentParser):
    """argparse with its errors on one line (``ctlab: error: ...``, exit status 2) instead of
    the usage text."""

    def error(self, message):
        raise UserError(message)


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="ctlab", description="Cook-Torrance Lab batch tools")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS.values():
        p = sub.add_parser(command.name, help=command.help)
        for option in command.options:
            option.add_to(p)
        p.set_defaults(func=command.run)
    return parser


# A value that starts with "-" and is a number or a list of numbers ("-0.45,-0.55,0.7",
# "-1e-05", "-inf"): argparse would take it for an option.
_NEGATIVE_VALUE = re.compile(r"^-(\d|\.\d|inf|nan)", re.I)


def join_negative_values(argv: list, value_flags=VALUE_FLAGS) -> list:
    """``--flag -0.5,...`` -> ``--flag=-0.5,...`` for the options that take a value."""
    out, i = [], 0
    while i < len(argv):
        a = str(argv[i])
        if a in value_flags and i + 1 < len(argv) and _NEGATIVE_VALUE.match(str(argv[i + 1])):
            out.append(f"{a}={argv[i + 1]}")
            i += 2
            continue
        out.append(a)
        i += 1
    return out


def argv(command: str, *words, **values) -> list:
    """A command line for ``command`` with options given by their destination names, from
    the command's own options (``argv("matrix", "--out", OUT, sun_dir=(x, y, z),
    samples=64)``, ``argv("plot", out=OUT, g_model="cook_torrance")``). Values are written as
    ``--flag=value``, so a negative number or a list starting with "-" cannot be read as an
    option; an unknown name is a KeyError here rather than a parse error in the child."""
    out = [command, *map(str, words)]
    options = {o.dest: o for o in COMMANDS[command].options if not o.positional}
    for dest, value in values.items():
        option = options[dest]
        if not option.takes_value:
            if value:
                out.append(option.flag)
            continue
        if isinstance(value, (tuple, list)):
            value = ",".join(f"{float(v):.9g}" for v in value)
        elif isinstance(value, float):
            value = f"{value:.9g}"
        out.append(f"{option.flag}={value}")
    return out
