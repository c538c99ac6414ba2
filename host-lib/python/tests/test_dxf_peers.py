"""DXF outputs against ezdxf and GEOS (issue 32 §1): every plan of `dxf_peer_plans` (written by
ezdxf, R12 to R2018, ASCII and binary) is dilated by the library, and its output must open and
audit clean in ezdxf, keep every entity that is not a cut as it was, and match GEOS's buffer of
the exact cut contours within 1 µm (`dxf_peer_checks`). Every DXF the Rust plan tests dilate
(`host-lib/plan/tests/corpus`, `fixtures`), the gauge's DXF and LibreCAD's part library (real
drawings; `cargo xtask test-python` installs it and says where) are opened and audited too.

`KERFMETER_DXF_PEER_REPORT=path` writes the figures of every plan there as JSON."""

import json
import os
from collections import Counter
from pathlib import Path

import pytest

import kerfmeter
from dxf_peer_checks import audit, deviation_um, output_rings_mm, untouched
from dxf_peer_plans import KINDS, R12_KINDS, VERSIONS, build

KERF_UM = 150.0
# The deviation allowed from GEOS's buffer (µm).
TOLERANCE_UM = 1.0

PLANS = [(kind, v, binary) for v in VERSIONS for kind in (R12_KINDS if v == "R12" else KINDS)
         for binary in (False, True)]
REPORT: list[dict] = []

PLAN_TESTS = Path(__file__).resolve().parents[2] / "plan" / "tests"
# The Rust plan tests' DXF inputs that dilate, with the units they need.
RUST_INPUTS = {
    "corpus/r12_polyline_unitless.dxf": "mm",
    "corpus/librecad_r2000_lwpolyline.dxf": None,
    "corpus/freecad_r2004_ellipse_spline_cm.dxf": None,
    "corpus/fusion_r2018_blocks_inch.dxf": None,
    "corpus/inkscape_r14_spline.dxf": None,
    "corpus/cad_r2000_straight_spline.dxf": None,
    "fixtures/cad_plate.dxf": None,
}


def assert_clean(path: Path):
    errors, fixes = audit(path)
    assert errors == [] and fixes == [], f"{path.name}: errors {errors}, fixes {fixes}"


@pytest.mark.parametrize("kind,version,binary", PLANS, ids=lambda p: str(p))
def test_an_ezdxf_plan_dilates_into_a_clean_dxf_within_a_micron_of_geos(tmp_path, kind, version, binary):
    plan = build(kind, version)
    source = plan.save(tmp_path, binary)
    out = tmp_path / f"{source.stem}-k150.dxf"
    report = kerfmeter.dilate(source, out, KERF_UM, units=plan.units_arg)
    assert out.read_bytes().startswith(b"999"), "ASCII, the record first"
    assert_clean(out)
    assert untouched(source, out, plan.cut_handles) == []
    rings = output_rings_mm(out, plan.mm_per_unit)
    found = deviation_um(plan.rings_mm, KERF_UM, rings)
    REPORT.append({"kind": kind, "version": version, "binary": binary, "contours": found.rings,
                   "worst_um": found.worst_um, "unmatched": found.unmatched,
                   "dilated": report["contours_dilated"]})
    assert found.unmatched == 0, f"{found.unmatched} rings unpaired of {found.rings} ({len(rings)} out)"
    assert found.worst_um <= TOLERANCE_UM, f"{found.worst_um:.3f} µm from GEOS"
    if binary:
        assert any("written as ASCII" in n for n in report["notes"]), report["notes"]


@pytest.mark.parametrize("name", sorted(RUST_INPUTS))
def test_every_dxf_the_plan_tests_dilate_opens_and_audits_clean(tmp_path, name):
    """These plans were written by hand for the Rust tests, one with a flaw ezdxf fixes (a root
    dictionary without its owner): the output may carry the input's own fixes, no other."""
    source, out = PLAN_TESTS / name, tmp_path / "out.dxf"
    kerfmeter.dilate(source, out, KERF_UM, units=RUST_INPUTS[name])
    errors, fixes = audit(out)
    _, fixes_before = audit(source)
    assert errors == [], errors
    assert not Counter(fixes) - Counter(fixes_before), f"fixes {fixes}, the input's {fixes_before}"


def test_librecads_part_library_dilates_into_clean_dxf_or_is_refused_by_name(tmp_path):
    """LibreCAD's part library (Debian's librecad-data, which `cargo xtask test-python`
    installs): 1,335 real drawings, mostly schematic symbols. Each dilates (R12 ones with
    --units mm) or is refused with a PlanError (open lines are no cut, symbols touch), never
    another failure; every output opens in ezdxf and its audit finds no error, and fixes nothing
    the input did not need."""
    library = os.environ.get("KERFMETER_LIBRECAD_PARTS")
    if not library:
        pytest.skip("KERFMETER_LIBRECAD_PARTS is set by cargo xtask test-python")
    files = sorted(Path(library).rglob("*.dxf"))
    dilated, refused, unclean = 0, 0, []
    for k, source in enumerate(files):
        out = tmp_path / f"{k}.dxf"
        try:
            kerfmeter.dilate(source, out, KERF_UM, units="mm")
        except kerfmeter.PlanError:
            refused += 1
            continue
        dilated += 1
        errors, fixes = audit(out)
        _, fixes_before = audit(source)
        if errors or Counter(fixes) - Counter(fixes_before):
            unclean.append((source.name, errors[:2], fixes[:2]))
        out.unlink()
    REPORT.append({"librecad_files": len(files), "dilated": dilated, "refused": refused,
                   "unclean": len(unclean)})
    assert len(files) > 1000 and dilated > 400, (len(files), dilated)
    assert unclean == []


def test_the_gauge_dxf_opens_and_audits_clean(tmp_path):
    out = tmp_path / "gauge.dxf"
    kerfmeter.gauge(out, label=True, test_piece_kerf_um=150)
    assert_clean(out)


def teardown_module():
    path = os.environ.get("KERFMETER_DXF_PEER_REPORT")
    if path and REPORT:
        Path(path).write_text(json.dumps(REPORT, indent=1))
