"""``ctlab compare``: two render folders, cell by cell (core/compare.py)."""

from __future__ import annotations

from .options import DIR_A, DIR_B, OUT, Command, check_path
from .output import say


def run(args) -> None:
    from ...core.compare import compare

    out = check_path(args.out, "--out")
    result = compare(
        check_path(args.dir_a, "first render folder"),
        check_path(args.dir_b, "second render folder"),
        out,
    )
    o = result["overall"]
    psnr = "identical images" if o["psnr_db"] is None else f"PSNR {o['psnr_db']:.2f} dB"
    say(
        f"compared {len(result['cells'])} cells: mean CIEDE2000 {o['ciede2000_mean']:.2f}, "
        f"{psnr} -> {out / 'metrics.json'}, diff.png"
    )


COMMAND = Command(
    "compare",
    "compare two render folders",
    (DIR_A, DIR_B, OUT.but(help="output folder for metrics.json and diff.png")),
    run,
)
