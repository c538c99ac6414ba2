"""The Python code of docs/python.md runs as shown, on the twin: the page's first example, with
`Kerfmeter.discover()` (a real device) swapped for `Kerfmeter.sim()` and its plan for the
repository's example plan, must measure and dilate without an error."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
PAGE = ROOT / "docs" / "python.md"


def python_blocks(markdown: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", markdown, re.S | re.M)


def test_the_pages_example_measures_and_dilates_on_the_twin(tmp_path):
    example = python_blocks(PAGE.read_text())[0]
    assert "kerfmeter.Kerfmeter.discover()" in example, "the example's device changed: update this test"
    plan = ROOT / "examples" / "box-parts.svg"
    runnable = (
        example.replace("kerfmeter.Kerfmeter.discover()", "kerfmeter.Kerfmeter.sim()")
        .replace('"plan.svg"', repr(str(plan)))
        .replace('"plan-k.svg"', repr(str(tmp_path / "plan-k.svg")))
    )
    scope: dict = {}
    exec(compile(runnable, str(PAGE), "exec"), scope)
    assert (tmp_path / "plan-k.svg").exists()
    assert 100 < scope["result"].kerf_um < 200
