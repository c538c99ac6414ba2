"""Make boxes.py's plans for the recompensation test (`plan_recompensation_boxes`): every
generator (or those named), each with its defaults at several burns.

    python boxes_plans.py BOXES_SRC OUT_DIR [--burn 0 --burn 0.05 --burn 0.1] [--only NAME ...]

BOXES_SRC is a boxes.py checkout (boxes.py is not on PyPI: its `boxes` there is another
project); its dependencies must be installed in this Python. Each plan is written as
`NAME.burnB.svg` with the arguments `--burn=B --spacing=0.5:-2B`: boxes.py spaces parts by
2·burn more than `--spacing` asks, and the extra space given cancels that, so that the parts lie
where they lie at burn 0. boxes.py's `reproducible` metadata leaves the date out.

A generator that fails at a burn (some need a layout file, some refuse their defaults) is named
on stderr with its error and its plans left out. One line per generator on stdout: its name and
seconds taken, or `failed`.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import time
import traceback
from pathlib import Path


def generators(src: Path) -> dict[str, type]:
    """boxes.py's generators by class name."""
    sys.path.insert(0, str(src))
    import boxes.generators

    found = boxes.generators.getAllBoxGenerators()
    return {cls.__name__: cls for cls in found.values()}


def plan(cls: type, burn: float) -> bytes:
    """The SVG boxes.py writes for `cls` with its defaults at `burn`."""
    box = cls()
    box.parseArgs([f"--burn={burn}", f"--spacing=0.5:{-2 * burn}"])
    box.metadata["reproducible"] = True
    # Generators print notes of their own; stdout is this script's report.
    with contextlib.redirect_stdout(io.StringIO()):
        box.open()
        box.render()
        data = box.close()
    return data.read()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("src", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--burn", type=float, action="append")
    ap.add_argument("--only", nargs="*")
    args = ap.parse_args()
    burns = args.burn or [0.0, 0.05, 0.1]
    args.out.mkdir(parents=True, exist_ok=True)
    found = generators(args.src)
    names = sorted(args.only or found)
    for name in names:
        start = time.monotonic()
        try:
            plans = {b: plan(found[name], b) for b in burns}
        except Exception:  # noqa: BLE001 - any generator's failure is reported, not fatal
            print(f"{name}: {traceback.format_exc(limit=1)}", file=sys.stderr)
            print(f"{name} failed", flush=True)
            continue
        for b, svg in plans.items():
            (args.out / f"{name}.burn{b:g}.svg").write_bytes(svg)
        print(f"{name} {time.monotonic() - start:.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
