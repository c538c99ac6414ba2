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

import ezdxf
import ezdxf.colors
import ezdxf.units
import pytest

import kerfmeter
from dxf_peer_checks import (audit, deviation_um, duplicate_handles, entities_by_handle,
                             objects_changed, output_rings_mm, untouched)
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
    assert objects_changed(source, out) == []
    assert duplicate_handles(out) == []
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


@pytest.mark.parametrize("version", [v for v in VERSIONS if v != "R12"])
@pytest.mark.parametrize("binary", [False, True])
def test_a_raster_image_and_its_imagedef_come_out_as_they_went_in(tmp_path, version, binary):
    """Issue 39 §2: a plan whose objects include an IMAGEDEF (LibreCAD's Complete-Lib-V.dxf
    came out of the retired whole-drawing writer with its pixel size under codes 11/12 and 30
    handles given twice). Its IMAGE, IMAGEDEF, IMAGEDEF_REACTOR and RASTERVARIABLES keep their
    handles and tags, and the IMAGEDEF its pixel size as 11/21."""
    plan = build("circle", version)
    source = plan.save(tmp_path, binary)
    out = tmp_path / "out.dxf"
    kerfmeter.dilate(source, out, KERF_UM)
    kinds = Counter(tags[0][1] for tags in entities_by_handle(out, ("OBJECTS",)).values())
    assert {"IMAGEDEF": 1, "IMAGEDEF_REACTOR": 1, "RASTERVARIABLES": 1}.items() <= kinds.items()
    assert "IMAGE" in {tags[0][1] for tags in entities_by_handle(out).values()}
    (image_def,) = [t for t in entities_by_handle(out, ("OBJECTS",)).values() if t[0][1] == "IMAGEDEF"]
    codes = [c for c, _ in image_def]
    assert codes[codes.index(11):codes.index(11) + 2] == [11, 21], image_def
    assert_clean(out)
    assert objects_changed(source, out) == []
    assert untouched(source, out, plan.cut_handles) == []
    assert duplicate_handles(out) == []


def test_librecads_drawing_with_an_image_dilates_into_clean_dxf(tmp_path):
    """LibreCAD's plan/architect/Complete-Lib-V.dxf (mm, an IMAGE of a BMP): its blocks' outlines
    branch (refused by the loop rule of issue 39 §1), so its BORDER layer is cut: one closed
    outline, dilated. The output opens and audits with no error and only the input's own fix
    (an IMAGEDEF's owner), its objects and non-cut entities as they were, no handle twice."""
    library = os.environ.get("KERFMETER_LIBRECAD_PARTS")
    if not library:
        pytest.skip("KERFMETER_LIBRECAD_PARTS is set by cargo xtask test-python")
    source = Path(library) / "library" / "plan" / "architect" / "Complete-Lib-V.dxf"
    out = tmp_path / "out.dxf"
    report = kerfmeter.dilate(source, out, KERF_UM, cut_layers=["BORDER"])
    assert report["contours_dilated"] == 1, report
    errors, fixes = audit(out)
    _, fixes_before = audit(source)
    assert errors == [] and not Counter(fixes) - Counter(fixes_before), (errors, fixes)
    assert objects_changed(source, out) == []
    assert duplicate_handles(out) == []
    changed = untouched(source, out, set())
    assert len(changed) == 1 and changed[0].startswith("LWPOLYLINE"), changed


def test_every_aci_colour_is_cut_by_its_number_and_by_ezdxfs_rgb_both_ways(tmp_path):
    """Issue 39 §3, against ezdxf's own ACI table (`ezdxf.colors.aci2rgb`): for each index
    1–255 (7 is black on the laser's sheet), a circle in that ACI is cut by `--cut-color` of its
    RGB, and a circle in that RGB as a true colour (group 420) by `--cut-color` of its index."""
    wrong = []
    for index in range(1, 256):
        rgb = (0, 0, 0) if index == 7 else tuple(ezdxf.colors.aci2rgb(index))
        hex_rgb = "#{:02X}{:02X}{:02X}".format(*rgb)
        for by_index in (True, False):
            doc = ezdxf.new("R2018")
            doc.units = ezdxf.units.MM
            circle = doc.modelspace().add_circle((0, 0), 5)
            if by_index:
                circle.dxf.color = index
            else:
                circle.rgb = rgb
            source = tmp_path / "aci.dxf"
            doc.saveas(source)
            asked = hex_rgb if by_index else str(index)
            try:
                report = kerfmeter.dilate(source, None, KERF_UM, dry_run=True, cut_colors=[asked])
                if report["contours_dilated"] != 1:
                    wrong.append((index, by_index, report["contours_dilated"]))
            except kerfmeter.PlanError as e:
                wrong.append((index, by_index, str(e)[:80]))
    assert wrong == []


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
