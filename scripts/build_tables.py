"""Write the model's tables the extension ships (addon/data, with dfg.json, their parameters),
so that no first use integrates them: per G option, dfg_<G>.npy (the split-sum's scale and
bias of specColor and the Disney factor, ibl_bake.dfg_table) and dominant_<G>.npy (the
corrected split-sum's dominant direction, ibl_bake.dominant_table), integrated for this
model's D and each G (addon/core/ibl_bake.py); and the node group's correction tables,
correction_tables.npz with correction_tables.json (addon/core/correction_tables.py). Run it
after changing the model or the tables' parameters; tests/render/test_ibl_bake.py fails until
it is run.

    ./scripts/dev.sh build_tables
"""

import io
import json
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402

from addon.core import correction_tables, ibl_bake  # noqa: E402
from addon.core.files import DATA_DIR, atomic_path, write_text  # noqa: E402
from addon.core.model import G_MODELS  # noqa: E402


def main() -> None:
    DATA_DIR.mkdir(parents=True, exist_ok=True)
    for g in G_MODELS:
        for name, table in (
            (f"dfg_{g}", ibl_bake.dfg_table),
            (f"dominant_{g}", ibl_bake.dominant_table),
        ):
            buf = io.BytesIO()
            np.save(buf, table(g))
            with atomic_path(DATA_DIR / f"{name}.npy") as tmp:
                tmp.write_bytes(buf.getvalue())
            print(f"wrote {DATA_DIR / f'{name}.npy'}")
    write_text(DATA_DIR / "dfg.json", json.dumps(ibl_bake.table_signature(), indent=2))
    name = correction_tables.SHIPPED
    buf = io.BytesIO()
    np.savez_compressed(buf, **correction_tables.all_tables())
    with atomic_path(DATA_DIR / f"{name}.npz") as tmp:
        tmp.write_bytes(buf.getvalue())
    signature = correction_tables.table_signature()
    write_text(DATA_DIR / f"{name}.json", json.dumps(signature, indent=2))
    print(f"wrote {DATA_DIR / f'{name}.npz'}")


if __name__ == "__main__":
    main()
