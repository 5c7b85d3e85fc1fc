"""What the command line prints: its own progress as lines (``[ctlab HH:MM:SS] ...``), or,
with $CTLAB_JSON_EVENTS set (the add-on's background job), one JSON object per event;
warnings on stderr; and the pipeline's events (jobs/pipeline.py ``Events``), with the
cancel request of the background job: the file named by $CTLAB_CANCEL_FILE exists."""

from __future__ import annotations

import json
import os
import sys
import time

from ..pipeline import Events


def _json_events() -> bool:
    return bool(os.environ.get("CTLAB_JSON_EVENTS"))


def say(message: str) -> None:
    if _json_events():
        print(json.dumps({"event": "note", "message": message}), flush=True)
    else:
        print(f"[ctlab {time.strftime('%H:%M:%S')}] {message}", flush=True)


def warn(message: str) -> None:
    print(f"ctlab: warning: {message}", file=sys.stderr, flush=True)


def progress(step: int, total: int, message: str) -> None:
    if _json_events():
        print(
            json.dumps({"event": "progress", "step": step, "total": total, "message": message}),
            flush=True,
        )
    else:
        say(f"[{step}/{total}] {message}")


def _cancel_requested() -> bool:
    flag = os.environ.get("CTLAB_CANCEL_FILE")
    return bool(flag) and os.path.exists(flag)


def events() -> Events:
    return Events(
        progress=progress, note=lambda m: say(f"  {m}"), cancelled=_cancel_requested, warn=warn
    )
