"""What a dilated DXF is checked for, with ezdxf and GEOS (shapely), implementations nobody on
this project wrote:

* `audit`: ezdxf opens it (`ezdxf.readfile`) and `doc.audit()` finds no error and fixes nothing;
* `untouched`: every entity of the input's ENTITIES and BLOCKS sections that is not a cut
  comes out with the same handle and the same group codes and values, in order (read by
  ezdxf's own tag loaders, ASCII or binary: a binary input comes back as ASCII);
* `objects_changed`: the same for every object of the OBJECTS section (an IMAGEDEF, its
  reactor, dictionaries, layouts), none of which a dilation touches;
* `duplicate_handles`: no handle is given twice anywhere in the file;
* `deviation_um`: the dilated cuts against a GEOS buffer of the exact cut contours.

**The metric.** The input's cut contours are sampled from their true curves (`dxf_peer_plans`,
no chord more than 0.01 µm from its curve), their region taken even-odd (nested contours are
holes, then islands), and buffered by GEOS by half the kerf with round joins (64 segments a
quarter circle: a join's chord is within 0.006 µm of its arc at a 75 µm radius): outer contours
grow, holes shrink. The output's closed cut contours (LWPOLYLINE and POLYLINE with bulges,
CIRCLE, blocks expanded) are sampled from their arcs the same way. Each buffer boundary ring is
paired with the output ring nearest it, and their distance is the symmetric Hausdorff distance
(GEOS's, each ring's vertices to the other ring's segments). With both sides sampled within
0.01 µm of their curves the figure is the true Hausdorff distance of the exact curves within
0.03 µm; the count of rings must match too (a cut left undilated, lost or doubled fails).
"""

from __future__ import annotations

import io
import math
import re
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import ezdxf
import shapely
from ezdxf.lldxf.tagger import ascii_tags_loader, binary_tags_loader
from shapely.geometry import LinearRing, Polygon

from dxf_peer_plans import Point, arc_points, bulged_ring, closed

# Group code ranges whose values are numbers (others are text), as the DXF reference types them.
FLOAT_CODES = [(10, 59), (110, 149), (210, 239), (460, 469), (1010, 1059)]
INT_CODES = [(60, 99), (160, 179), (270, 289), (290, 299), (370, 389), (400, 409), (420, 429),
             (440, 459), (1060, 1071)]
BINARY_CODES = [(310, 319), (1004, 1004)]


def _in(code: int, ranges) -> bool:
    return any(a <= code <= b for a, b in ranges)


def audit(path: Path) -> tuple[list[str], list[str]]:
    """ezdxf's audit of the file: (errors, fixes), as messages. Raises when it cannot be read."""
    doc = ezdxf.readfile(path)
    auditor = doc.audit()
    return [e.message for e in auditor.errors], [f.message for f in auditor.fixes]


# --- entities as tags ------------------------------------------------------------------------


def _value(code: int, value):
    """A tag's value in one form whatever the file's (text in ASCII, typed in binary)."""
    if _in(code, BINARY_CODES):
        return value.hex().upper() if isinstance(value, (bytes, bytearray)) else str(value).strip().upper()
    if _in(code, FLOAT_CODES):
        return float(value)
    if _in(code, INT_CODES):
        return int(float(value))
    return value if isinstance(value, str) else str(value)


def _tags(path: Path):
    data = path.read_bytes()
    if data.startswith(b"AutoCAD Binary DXF"):
        return binary_tags_loader(data)
    version = re.search(rb"\$ACADVER\s+1\s+(AC\d{4})", data[:4096])
    utf8 = version is not None and version.group(1) >= b"AC1021"
    text = data.decode("utf8" if utf8 else "cp1252", errors="surrogateescape")
    return ascii_tags_loader(io.StringIO(text, newline=None), skip_comments=True)


def entities_by_handle(path: Path, sections=("ENTITIES", "BLOCKS")) -> dict[str, list[tuple[int, object]]]:
    """Every entity (each VERTEX, ATTRIB and SEQEND on its own) of the ENTITIES and BLOCKS
    sections (or of `sections`), BLOCK and ENDBLK included, by handle: its tags, normalised."""
    found: dict[str, list[tuple[int, object]]] = {}
    section, prev, current = None, None, None
    for tag in _tags(path):
        code, value = tag.code, tag.value
        if code == 2 and prev == (0, "SECTION"):
            section = value
        if code == 0:
            current = None
            if section in sections and value not in ("ENDSEC", "SECTION"):
                current = [(0, value)]
        elif current is not None:
            current.append((code, _value(code, value)))
            if code == 5 and len(current) == 2:
                found[str(value).upper()] = current
        prev = (code, value)
    return found


def untouched(before: Path, after: Path, cut_handles: set[str]) -> list[str]:
    """Entities that are not cuts and did not come out as they went in, and new entities that
    are not polylines or circles, in words (none is right)."""
    old, new = entities_by_handle(before), entities_by_handle(after)
    cuts = {h.upper() for h in cut_handles}
    problems = []
    for handle, tags in old.items():
        if handle in cuts:
            continue
        if handle not in new:
            problems.append(f"{tags[0][1]} {handle} is gone")
        elif new[handle] != tags:
            diff = [(a, b) for a, b in zip(tags, new[handle]) if a != b][:3]
            problems.append(f"{tags[0][1]} {handle} changed: {diff or 'its length'}")
    for handle, tags in new.items():
        if handle not in old and tags[0][1] not in ("LWPOLYLINE", "POLYLINE", "VERTEX", "SEQEND"):
            problems.append(f"a new {tags[0][1]} {handle}")
    return problems


def objects_changed(before: Path, after: Path) -> list[str]:
    """Objects of the OBJECTS section that did not come out as they went in (same handle, same
    group codes and values, in order), or that are new, in words (none is right)."""
    old = entities_by_handle(before, ("OBJECTS",))
    new = entities_by_handle(after, ("OBJECTS",))
    problems = []
    for handle, tags in old.items():
        if handle not in new:
            problems.append(f"{tags[0][1]} {handle} is gone")
        elif new[handle] != tags:
            diff = [(a, b) for a, b in zip(tags, new[handle]) if a != b][:3]
            problems.append(f"{tags[0][1]} {handle} changed: {diff or 'its length'}")
    problems += [f"a new {tags[0][1]} {h}" for h, tags in new.items() if h not in old]
    return problems


def duplicate_handles(path: Path) -> list[str]:
    """Handles given to more than one entity, table entry or object (code 5, or 105 for a
    DIMSTYLE, right after the code 0 that starts it)."""
    seen: Counter[str] = Counter()
    prev = None
    for tag in _tags(path):
        if tag.code in (5, 105) and prev == 0:
            seen[str(tag.value).upper()] += 1
        prev = tag.code
    return sorted(h for h, n in seen.items() if n > 1)


# --- the cuts of the output ------------------------------------------------------------------


CUT_ACI = {1, 5, 7}


def _aci(e, doc, parent: int | None, parent_layer: str | None) -> int | None:
    """The colour an entity is drawn in (ACI), BYBLOCK and layer 0 taken from its INSERT."""
    c = e.dxf.get("color", 256)
    layer = e.dxf.get("layer", "0")
    if layer == "0" and parent_layer is not None:
        layer = parent_layer
    if c == 0:
        return parent
    if c == 256:
        return doc.layers.get(layer).dxf.color if doc.layers.has_entry(layer) else None
    return c


def _ring(e, mm: float) -> list[Point] | None:
    """A closed cut entity's contour in mm; None for any other."""
    kind = e.dxftype()
    if kind == "CIRCLE":
        c = e.ocs().to_wcs(e.dxf.center)
        ring = closed(arc_points(c.x, c.y, e.dxf.radius, 0, 2 * math.pi))
    elif kind == "LWPOLYLINE":
        v = [tuple(p) for p in e.get_points("xyb")]
        if not (e.closed or math.dist(v[0][:2], v[-1][:2]) < 1e-9):
            return None
        ring = bulged_ring(v[:-1] if not e.closed else v)
    elif kind == "POLYLINE":
        v = [(p.dxf.location.x, p.dxf.location.y, p.dxf.bulge) for p in e.vertices]
        if not (e.is_closed or math.dist(v[0][:2], v[-1][:2]) < 1e-9):
            return None
        ring = bulged_ring(v[:-1] if not e.is_closed else v)
    else:
        return None
    return [(x * mm, y * mm) for x, y in ring]


def output_rings_mm(path: Path, mm: float) -> list[list[Point]]:
    """The closed cut contours of a DXF in mm: model space, and blocks through their INSERTs
    (where no cut should be left)."""
    doc = ezdxf.readfile(path)
    rings = []

    def walk(entities, parent, parent_layer):
        for e in entities:
            aci = _aci(e, doc, parent, parent_layer)
            if e.dxftype() == "INSERT":
                layer = e.dxf.layer if e.dxf.layer != "0" or parent_layer is None else parent_layer
                walk(e.virtual_entities(), aci, layer)
            elif aci in CUT_ACI and (ring := _ring(e, mm)) is not None:
                rings.append(ring)

    walk(doc.modelspace(), None, None)
    return rings


# --- against GEOS ----------------------------------------------------------------------------


@dataclass
class Deviation:
    worst_um: float
    rings: int
    unmatched: int


def reference_rings(rings_mm: list[list[Point]], kerf_um: float) -> list[LinearRing]:
    """GEOS's dilation of the cut contours: their even-odd region buffered by half the kerf."""
    region = None
    for ring in rings_mm:
        polygon = shapely.make_valid(Polygon(ring))
        region = polygon if region is None else region.symmetric_difference(polygon)
    grown = region.buffer(kerf_um / 2000.0, quad_segs=64, join_style="round")
    polygons = getattr(grown, "geoms", [grown])
    out = []
    for polygon in polygons:
        out.append(polygon.exterior)
        out.extend(polygon.interiors)
    return out


def deviation_um(rings_mm: list[list[Point]], kerf_um: float, output: list[list[Point]]) -> Deviation:
    """The worst Hausdorff distance (µm) between GEOS's dilation and the output's rings, each
    reference ring paired with the nearest output ring; rings left unpaired on either side."""
    reference = reference_rings(rings_mm, kerf_um)
    candidates = [LinearRing(r) for r in output]
    boxes = [c.bounds for c in candidates]
    used: set[int] = set()
    worst = 0.0
    for ring in reference:
        near = [k for k, b in enumerate(boxes) if k not in used and _boxes_near(b, ring.bounds)]
        if not near:
            continue
        d, k = min((shapely.hausdorff_distance(ring, candidates[k]), k) for k in near)
        used.add(k)
        worst = max(worst, d * 1000.0)
    unmatched = (len(reference) - len(used)) + (len(candidates) - len(used))
    return Deviation(worst, len(reference), unmatched)


def _boxes_near(a, b, mm: float = 0.01) -> bool:
    return all(abs(p - q) <= mm for p, q in zip(a, b))
