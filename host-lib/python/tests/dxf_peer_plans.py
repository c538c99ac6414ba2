"""Cutting plans written by ezdxf (not by the `dxf` crate that Kerfmeter reads with), each with
its cut contours known exactly.

Every plan is built from shapes whose true curves this module samples itself (arcs and bulges
from their centres and radii, ellipses from their axes, splines through ezdxf's own B-spline
evaluation), densely: no chord is more than `TOL_MM` (0.01 µm) from its curve, in the drawing's
units times the largest block scale. The cut contours are returned in document mm, block
insertions applied (rotation, mirror, unequal scales, arrays, nesting), so that a dilation can be
compared with a GEOS buffer of them (see `dxf_peer_checks`).

What is covered, one plan builder per kind, written as R12 (where the kind exists there: R12 has
no LWPOLYLINE, ELLIPSE or SPLINE) and as R2000 to R2018, ASCII and binary:

* `lwpolyline`: LWPOLYLINEs with bulges (rounded plate, slot, hole with an island, one closed by
  ending at its start);
* `polyline`: the same as 2-D POLYLINEs with bulges;
* `circle`: CIRCLE holes, and an island in a round hole;
* `chain`: LINE/ARC chains, some pieces drawn backwards;
* `spline`: a clamped cubic SPLINE ending at its start, a closed periodic one, and a rational
  quadratic one that is exactly a circle;
* `ellipse`: a rotated full ELLIPSE, a half ELLIPSE closed by a LINE, a full one as a hole;
* `blocks`: a part made of a bulged outline, a circle and an ARC/LINE chain in a block (layer 0
  and BYBLOCK colour, as CAD programs draw them), inserted as drawn, rotated, mirrored, stretched
  unequally, as a 2 × 2 array, and nested in another block inserted rotated and mirrored; plus an
  INSERT with attributes of a block that holds no cut;
* `inch`: a plate drawn in inches.

Every plan also carries entities that are not cuts (green MTEXT with a true colour, TEXT, an
engraving polyline, a HATCH, a DIMENSION with its block, a POINT, an open red slit), which a
dilation must leave exactly as they were.

Run as a script, it writes the plans into a folder: `python dxf_peer_plans.py OUT_DIR`.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import ezdxf
from ezdxf import units

# The largest distance (drawing units) of a sampled chord from its true curve.
TOL_MM = 1e-5

# DXF versions as ezdxf names them, R12 first.
VERSIONS = ["R12", "R2000", "R2004", "R2007", "R2010", "R2013", "R2018"]

# Kinds that exist in R12 (no LWPOLYLINE, ELLIPSE or SPLINE there).
R12_KINDS = ["polyline", "circle", "chain", "blocks", "inch"]
KINDS = ["lwpolyline", "polyline", "circle", "chain", "spline", "ellipse", "blocks", "inch"]

CUT = {"layer": "CUT"}  # red by its layer
ENGRAVE = {"layer": "ENGRAVE"}  # green by its layer

Point = tuple[float, float]
Affine = tuple[float, float, float, float, float, float]  # x' = a x + c y + e, y' = b x + d y + f
IDENTITY: Affine = (1.0, 0.0, 0.0, 1.0, 0.0, 0.0)


@dataclass
class Plan:
    """One plan: its document, its cut contours in mm (document frame), and the handles of the
    entities that are cuts (which a dilation may change or remove)."""

    name: str
    kind: str
    version: str
    doc: ezdxf.document.Drawing
    mm_per_unit: float
    units_arg: str | None  # what `--units` must say (R12 has no $INSUNITS)
    rings_mm: list[list[Point]] = field(default_factory=list)
    cut_handles: set[str] = field(default_factory=set)

    def save(self, folder: Path, binary: bool) -> Path:
        path = folder / f"{self.name}{'-bin' if binary else ''}.dxf"
        self.doc.saveas(path, fmt="bin" if binary else "asc")
        return path


# --- exact curves, sampled -------------------------------------------------------------------


def arc_points(cx: float, cy: float, r: float, start: float, sweep: float) -> list[Point]:
    """An arc (radians, sweep signed: counter-clockwise positive) within TOL_MM."""
    step = 2.0 * math.acos(max(-1.0, 1.0 - TOL_MM / r))
    n = max(2, math.ceil(abs(sweep) / step))
    return [
        (cx + r * math.cos(start + sweep * k / n), cy + r * math.sin(start + sweep * k / n))
        for k in range(n + 1)
    ]


def bulge_points(p: Point, q: Point, bulge: float) -> list[Point]:
    """The segment from p to q with a DXF bulge (tan of a quarter of its signed sweep)."""
    if bulge == 0.0:
        return [p, q]
    dx, dy = q[0] - p[0], q[1] - p[1]
    k = (1.0 - bulge * bulge) / (4.0 * bulge)
    cx, cy = (p[0] + q[0]) / 2 - dy * k, (p[1] + q[1]) / 2 + dx * k
    r = math.hypot(p[0] - cx, p[1] - cy)
    start = math.atan2(p[1] - cy, p[0] - cx)
    return arc_points(cx, cy, r, start, 4.0 * math.atan(bulge))


def bulged_ring(vertices: list[tuple[float, float, float]]) -> list[Point]:
    """A closed polyline of (x, y, bulge) vertices."""
    ring: list[Point] = []
    for i, (x, y, b) in enumerate(vertices):
        nx, ny, _ = vertices[(i + 1) % len(vertices)]
        ring.extend(bulge_points((x, y), (nx, ny), b)[:-1])
    return ring


def ellipse_points(center: Point, major: Point, ratio: float, t0: float, t1: float) -> list[Point]:
    """An elliptic arc from parameter t0 to t1 (counter-clockwise) within TOL_MM."""
    a = math.hypot(*major)
    b = a * ratio
    minor = (-major[1] * ratio, major[0] * ratio)
    step = math.sqrt(8.0 * TOL_MM * b * b / a**3)
    n = max(2, math.ceil((t1 - t0) / step))
    out = []
    for k in range(n + 1):
        t = t0 + (t1 - t0) * k / n
        c, s = math.cos(t), math.sin(t)
        out.append((center[0] + major[0] * c + minor[0] * s, center[1] + major[1] * c + minor[1] * s))
    return out


def spline_points(spline) -> list[Point]:
    """A SPLINE entity's curve, evaluated by ezdxf's B-spline over its valid domain (from knot
    `degree` to knot `count of control points`: a periodic spline's knot vector runs past it),
    each knot span cut in 64 and halved until a chord's middle is within TOL_MM / 4 of the
    curve."""
    curve = spline.construction_tool()
    knots, degree = list(curve.knots()), curve.degree
    start, end = knots[degree], knots[curve.count]

    def at(t: float) -> Point:
        p = curve.point(t)
        return (p.x, p.y)

    def refine(t0: float, p0: Point, t1: float, p1: Point, out: list[Point], depth: int = 0):
        tm = (t0 + t1) / 2
        pm = at(tm)
        chord_mid = ((p0[0] + p1[0]) / 2, (p0[1] + p1[1]) / 2)
        if depth < 30 and math.dist(pm, chord_mid) > TOL_MM / 4:
            refine(t0, p0, tm, pm, out, depth + 1)
            refine(tm, pm, t1, p1, out, depth + 1)
        else:
            out.append(p1)

    spans = sorted({k for k in knots if start <= k <= end})
    params = [a + (b - a) * i / 64 for a, b in zip(spans, spans[1:]) for i in range(64)] + [end]
    points = [at(params[0])]
    for t0, t1 in zip(params, params[1:]):
        refine(t0, at(t0), t1, at(t1), points)
    return points


def closed(points: list[Point]) -> list[Point]:
    """A ring without its repeated last point."""
    if math.dist(points[0], points[-1]) < 1e-9:
        return points[:-1]
    return points


# --- transforms ------------------------------------------------------------------------------


def compose(outer: Affine, inner: Affine) -> Affine:
    a, b, c, d, e, f = outer
    a2, b2, c2, d2, e2, f2 = inner
    return (
        a * a2 + c * b2,
        b * a2 + d * b2,
        a * c2 + c * d2,
        b * c2 + d * d2,
        a * e2 + c * f2 + e,
        b * e2 + d * f2 + f,
    )


def apply(m: Affine, ring: list[Point]) -> list[Point]:
    a, b, c, d, e, f = m
    return [(a * x + c * y + e, b * x + d * y + f) for x, y in ring]


def insert_affine(at: Point, rotation_deg: float, sx: float, sy: float, base: Point) -> Affine:
    """An INSERT's map from block coordinates: at + R(rotation)·S(sx, sy)·(p − base)."""
    cos, sin = math.cos(math.radians(rotation_deg)), math.sin(math.radians(rotation_deg))
    m = (cos * sx, sin * sx, -sin * sy, cos * sy, 0.0, 0.0)
    return compose((1.0, 0.0, 0.0, 1.0, at[0], at[1]), compose(m, (1, 0, 0, 1, -base[0], -base[1])))


def scaled(ring: list[Point], mm: float) -> list[Point]:
    return [(x * mm, y * mm) for x, y in ring]


# --- building blocks -------------------------------------------------------------------------


def new_doc(version: str, insunits: int | None) -> ezdxf.document.Drawing:
    doc = ezdxf.new(version, setup=True)
    if insunits is not None and version != "R12":
        doc.units = insunits
    doc.layers.add("CUT", color=1)
    doc.layers.add("ENGRAVE", color=3)
    doc.layers.add("NOTES", color=8)
    return doc


def add_polygon(space, vertices, version: str, attribs: dict, record: set[str] | None, as_lw: bool):
    """A closed bulged polygon as an LWPOLYLINE (R2000+, when `as_lw`) or a 2-D POLYLINE;
    its handles (with its vertices' and SEQEND's) go into `record`."""
    if as_lw and version != "R12":
        e = space.add_lwpolyline(vertices, format="xyb", close=True, dxfattribs=attribs)
        handles = [e.dxf.handle]
    else:
        e = space.add_polyline2d(vertices, format="xyb", close=True, dxfattribs=attribs)
        handles = [e.dxf.handle, e.seqend.dxf.handle] + [v.dxf.handle for v in e.vertices]
    if record is not None:
        record.update(handles)
    return e


def rounded_rect(x0, y0, x1, y1, r) -> list[tuple[float, float, float]]:
    """A rectangle with corners rounded by r, counter-clockwise, as bulged vertices."""
    b = math.tan(math.pi / 8)  # a quarter turn
    return [
        (x0 + r, y0, 0.0), (x1 - r, y0, b), (x1, y0 + r, 0.0), (x1, y1 - r, b),
        (x1 - r, y1, 0.0), (x0 + r, y1, b), (x0, y1 - r, 0.0), (x0, y0 + r, b),
    ]


def slot(x0, x1, y, r) -> list[tuple[float, float, float]]:
    """A stadium slot along x, ends of radius r, as bulged vertices."""
    return [(x0, y - r, 0.0), (x1, y - r, 1.0), (x1, y + r, 0.0), (x0, y + r, 1.0)]


def add_decorations(doc, space, version: str) -> None:
    """Entities that are not cuts: each must come out of a dilation exactly as it went in."""
    if version != "R12":  # MTEXT came with R13
        mtext = space.add_mtext("engrave me\\Pline two", dxfattribs={**ENGRAVE, "char_height": 2.5})
        mtext.dxf.insert = (5, -10)
        if version >= "R2004":
            mtext.rgb = (0, 160, 0)
    space.add_text("TEXT label", height=3, dxfattribs={**ENGRAVE, "insert": (5, -16)})
    add_polygon(space, [(0, -30, 0), (10, -30, 0), (10, -25, 0.3)], version, ENGRAVE, None, True)
    space.add_point((1, -40), dxfattribs={"layer": "NOTES"})
    space.add_line((2, -45), (30, -45), dxfattribs=CUT)  # an open red slit: never dilated
    if version != "R12":
        hatch = space.add_hatch(color=3, dxfattribs=ENGRAVE)
        hatch.paths.add_polyline_path([(40, -30), (50, -30), (50, -20), (40, -20)], is_closed=True)
    dim = space.add_linear_dim(base=(0, -50), p1=(0, -48), p2=(30, -48), dxfattribs={"layer": "NOTES"})
    dim.render()
    if version != "R12":  # raster images came with R14; ezdxf writes them from R2000
        add_image(doc, space)


def add_image(doc, space) -> None:
    """A raster image reference, as LibreCAD's Complete-Lib-V.dxf carries one (issue 39 §2): an
    IMAGE in model space, its IMAGEDEF (pixel size in codes 10/20, pixel's size in 11/21, which a
    whole-drawing writer once wrote as 11/12), the IMAGEDEF_REACTOR between them and the drawing's
    RASTERVARIABLES, all in OBJECTS. The file it names is never opened."""
    doc.set_raster_variables(frame=0, quality=1, units="mm")
    image_def = doc.add_image_def(filename="engraving/logo.png", size_in_pixel=(640, 360))
    space.add_image(image_def, insert=(100, -40), size_in_units=(64, 36), rotation=30,
                    dxfattribs=ENGRAVE)


# --- the plans -------------------------------------------------------------------------------


def plate_shapes(version: str, space, plan: Plan, as_lw: bool, ox: float = 0.0) -> None:
    """A rounded plate with a slot, a hole with an island, and a polygon closed by ending at its
    start (bulged polygons), drawn at x offset `ox`."""
    shapes = [
        rounded_rect(ox, 0, ox + 80, 50, 6),
        slot(ox + 10, ox + 30, 25, 4),
        rounded_rect(ox + 45, 8, ox + 75, 42, 3),
        [(ox + 60, 20, 1.0), (ox + 60, 30, 1.0)],  # an island: a circle of two bulges
    ]
    for vertices in shapes:
        add_polygon(space, vertices, version, CUT, plan.cut_handles, as_lw)
        plan.rings_mm.append(scaled(bulged_ring(vertices), plan.mm_per_unit))
    # Closed by its last vertex being its first (no closed flag), drawn clockwise.
    tri = [(ox + 35, 5, 0.0), (ox + 40, 15, 0.0), (ox + 45, 5, 0.0), (ox + 35, 5, 0.0)]
    if as_lw and version != "R12":
        e = space.add_lwpolyline(tri, format="xyb", close=False, dxfattribs=CUT)
        plan.cut_handles.add(e.dxf.handle)
    else:
        e = space.add_polyline2d(tri, format="xyb", close=False, dxfattribs=CUT)
        plan.cut_handles.update([e.dxf.handle, e.seqend.dxf.handle] + [v.dxf.handle for v in e.vertices])
    plan.rings_mm.append(scaled(closed([p[:2] for p in tri]), plan.mm_per_unit))


def circle_shapes(space, plan: Plan, version: str) -> None:
    plate = [(0, 0, 0.0), (100, 0, 0.0), (100, 60, 0.0), (0, 60, 0.0)]
    add_polygon(space, plate, version, CUT, plan.cut_handles, True)
    plan.rings_mm.append(scaled(bulged_ring(plate), plan.mm_per_unit))
    for (x, y, r) in [(10, 10, 2.5), (30, 10, 0.6), (50, 10, 4), (80, 40, 15), (80, 40, 6), (20, 45, 9.7)]:
        e = space.add_circle((x, y), r, dxfattribs=CUT)
        plan.cut_handles.add(e.dxf.handle)
        plan.rings_mm.append(scaled(closed(arc_points(x, y, r, 0, 2 * math.pi)), plan.mm_per_unit))


def chain_shapes(space, plan: Plan) -> None:
    """A rounded plate of 4 LINEs and 4 ARCs (two LINEs drawn backwards) and a keyhole of two
    ARCs and two LINEs."""
    x0, y0, x1, y1, r = 0.0, 0.0, 90.0, 60.0, 8.0
    pieces = []

    def line(p, q):
        pieces.append(space.add_line(p, q, dxfattribs=CUT))

    def arc(c, start, end):
        pieces.append(space.add_arc(c, r, start, end, dxfattribs=CUT))

    line((x0 + r, y0), (x1 - r, y0))
    arc((x1 - r, y0 + r), 270, 0)
    line((x1, y1 - r), (x1, y0 + r))  # backwards
    arc((x1 - r, y1 - r), 0, 90)
    line((x1 - r, y1), (x0 + r, y1))
    arc((x0 + r, y1 - r), 90, 180)
    line((x0, y0 + r), (x0, y1 - r))  # backwards
    arc((x0 + r, y0 + r), 180, 270)
    plan.rings_mm.append(scaled(closed(bulged_ring(rounded_rect(x0, y0, x1, y1, r))), plan.mm_per_unit))
    # Keyhole: a big arc (r 6 about (30, 30)) from −60° to 240°, a small arc (r 3 about (30, 18))
    # closing it from below, joined by two lines.
    big, small = (30.0, 30.0, 6.0), (30.0, 14.0, 3.0)
    a = math.degrees(math.asin(3.0 / 6.0))  # where the neck (x = 30 ± 3) meets the big circle
    pieces.append(space.add_arc(big[:2], big[2], -90 + a, 270 - a, dxfattribs=CUT))
    pieces.append(space.add_arc(small[:2], small[2], 180, 360, dxfattribs=CUT))
    ny = big[1] - 6.0 * math.cos(math.radians(a))
    line((33, ny), (33, 14))
    line((27, 14), (27, ny))
    key = arc_points(big[0], big[1], 6.0, math.radians(-90 + a), math.radians(360 - 2 * a))[:-1]
    key += [(27, ny)] + arc_points(30, 14, 3.0, math.pi, math.pi)[:-1] + [(33, 14)]
    plan.rings_mm.append(scaled(key, plan.mm_per_unit))
    plan.cut_handles.update(e.dxf.handle for e in pieces)


def spline_shapes(space, plan: Plan) -> None:
    add_polygon(space, rounded_rect(0, 0, 125, 60, 5), plan.version, CUT, plan.cut_handles, True)
    plan.rings_mm.append(bulged_ring(rounded_rect(0, 0, 125, 60, 5)))
    blob = [(10, 30), (20, 50), (40, 52), (45, 35), (35, 15), (15, 12), (10, 30)]
    clamped = space.add_open_spline(blob, degree=3, dxfattribs=CUT)
    periodic = space.add_spline(dxfattribs=CUT)
    periodic.set_closed([(60, 20, 0), (75, 12, 0), (90, 20, 0), (92, 40, 0), (75, 50, 0), (62, 40, 0)], degree=3)
    w = math.sqrt(0.5)
    circle = space.add_rational_spline(
        [(115, 30), (115, 40), (105, 40), (95, 40), (95, 30), (95, 20), (105, 20), (115, 20), (115, 30)],
        [1, w, 1, w, 1, w, 1, w, 1],
        degree=2,
        knots=[0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 4],
        dxfattribs=CUT,
    )
    for e in (clamped, periodic, circle):
        plan.cut_handles.add(e.dxf.handle)
        plan.rings_mm.append(closed(spline_points(e)))


def ellipse_shapes(space, plan: Plan) -> None:
    c, major, ratio = (60.0, 40.0), (55.0 * math.cos(0.3), 55.0 * math.sin(0.3)), 0.6
    outer = space.add_ellipse(c, (*major, 0), ratio, dxfattribs=CUT)
    plan.rings_mm.append(closed(ellipse_points(c, major, ratio, 0, 2 * math.pi)))
    half = space.add_ellipse((40, 40), (10, 0, 0), 0.5, 0, math.pi, dxfattribs=CUT)
    chord = space.add_line((30, 40), (50, 40), dxfattribs=CUT)
    plan.rings_mm.append(closed(ellipse_points((40, 40), (10, 0), 0.5, 0, math.pi)))
    hole = space.add_ellipse((75, 35), (0, 8, 0), 0.4, dxfattribs=CUT)
    plan.rings_mm.append(closed(ellipse_points((75, 35), (0, 8), 0.4, 0, 2 * math.pi)))
    plan.cut_handles.update(e.dxf.handle for e in (outer, half, chord, hole))


def part_block(doc, version: str, plan: Plan) -> list[list[Point]]:
    """Block PART (base point (5, 5)): a bulged outline on layer 0 in BYBLOCK colour, a circle
    on layer CUT, an ARC/LINE chain hole on layer 0 in BYBLOCK colour, and green text. Returns
    its cut rings in block coordinates."""
    block = doc.blocks.new("PART", base_point=(5, 5))
    byblock = {"layer": "0", "color": 0}
    outline = rounded_rect(0, 0, 30, 20, 3)
    add_polygon(block, outline, version, byblock, plan.cut_handles, True)
    hole = block.add_circle((8, 10), 3, dxfattribs=CUT)
    a1 = block.add_arc((20, 10), 3, 90, 270, dxfattribs=byblock)
    l1 = block.add_line((20, 7), (24, 7), dxfattribs=byblock)
    a2 = block.add_arc((24, 10), 3, 270, 90, dxfattribs=byblock)
    l2 = block.add_line((20, 13), (24, 13), dxfattribs=byblock)  # backwards
    block.add_text("PART", height=2, dxfattribs={**ENGRAVE, "insert": (2, 16)})
    plan.cut_handles.update(e.dxf.handle for e in (hole, a1, l1, a2, l2))
    return [
        bulged_ring(outline),
        closed(arc_points(8, 10, 3, 0, 2 * math.pi)),
        bulged_ring([(20, 13, 1.0), (20, 7, 0.0), (24, 7, 1.0), (24, 13, 0.0)]),
    ]


def block_shapes(doc, space, plan: Plan) -> None:
    """PART inserted as drawn, rotated, mirrored, stretched, as an array and nested in OUTER
    (itself inserted rotated and mirrored); LABEL (text and an attribute, no cut) inserted with
    its attribute."""
    rings = part_block(doc, plan.version, plan)
    base = (5.0, 5.0)
    inserts = [
        ((0, 0), 0, 1, 1, (1, 1), (1, 1)),
        ((80, 0), 30, 1, 1, (1, 1), (1, 1)),
        ((160, 0), 0, -1, 1, (1, 1), (1, 1)),
        ((180, 0), 0, 2, 1, (1, 1), (1, 1)),
        ((0, 60), 0, 1, 1, (2, 2), (40, 35)),  # rows, columns; row and column spacing
    ]
    for at, rot, sx, sy, size, spacing in inserts:
        ref = space.add_blockref("PART", at, dxfattribs={**CUT, "rotation": rot, "xscale": sx, "yscale": sy})
        if size != (1, 1):
            ref.grid(size=size, spacing=spacing)
        m = insert_affine(at, rot, sx, sy, base)
        for r in range(size[0]):
            for c in range(size[1]):
                cell = compose((1, 0, 0, 1, *rotate((c * spacing[1], r * spacing[0]), rot)), m)
                plan.rings_mm.extend(scaled(apply(cell, ring), plan.mm_per_unit) for ring in rings)
    outer = doc.blocks.new("OUTER")
    outer.add_blockref("PART", (10, 10), dxfattribs={"rotation": 90, "layer": "0", "color": 0})
    ring_hole = outer.add_circle((30, 5), 2, dxfattribs={"layer": "0", "color": 0})
    plan.cut_handles.add(ring_hole.dxf.handle)
    inner = insert_affine((10, 10), 90, 1, 1, base)
    for at, rot, sx, sy in [((110, 80), 15, 1, 1), ((200, 140), 0, 1, -1)]:
        space.add_blockref("OUTER", at, dxfattribs={**CUT, "rotation": rot, "xscale": sx, "yscale": sy})
        m = insert_affine(at, rot, sx, sy, (0, 0))
        plan.rings_mm.extend(apply(compose(m, inner), ring) for ring in rings)
        plan.rings_mm.append(apply(m, closed(arc_points(30, 5, 2, 0, 2 * math.pi))))
    label = doc.blocks.new("LABEL")
    label.add_text("LABEL", height=2, dxfattribs=ENGRAVE)
    label.add_attdef("NUMBER", (0, -4), dxfattribs={**ENGRAVE, "height": 2})
    ref = space.add_blockref("LABEL", (0, -60), dxfattribs=ENGRAVE)
    ref.add_auto_attribs({"NUMBER": "42"})


def rotate(p: Point, deg: float) -> Point:
    cos, sin = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return (cos * p[0] - sin * p[1], sin * p[0] + cos * p[1])


BUILDERS = {
    "lwpolyline": lambda doc, msp, plan: plate_shapes(plan.version, msp, plan, True),
    "polyline": lambda doc, msp, plan: plate_shapes(plan.version, msp, plan, False),
    "circle": lambda doc, msp, plan: circle_shapes(msp, plan, plan.version),
    "chain": lambda doc, msp, plan: chain_shapes(msp, plan),
    "spline": lambda doc, msp, plan: spline_shapes(msp, plan),
    "ellipse": lambda doc, msp, plan: ellipse_shapes(msp, plan),
    "blocks": block_shapes,
    "inch": lambda doc, msp, plan: plate_shapes(plan.version, msp, plan, True),
}


def build(kind: str, version: str) -> Plan:
    """The plan of `kind` as DXF `version`."""
    inch = kind == "inch"
    mm = 25.4 if inch else 1.0
    doc = new_doc(version, units.IN if inch else units.MM)
    units_arg = ("in" if inch else "mm") if version == "R12" else None
    plan = Plan(f"{kind}-{version}", kind, version, doc, mm, units_arg)
    msp = doc.modelspace()
    BUILDERS[kind](doc, msp, plan)
    add_decorations(doc, msp, version)
    return plan


def all_plans() -> list[Plan]:
    """Every kind in every version it exists in."""
    return [build(kind, v) for v in VERSIONS for kind in (R12_KINDS if v == "R12" else KINDS)]


if __name__ == "__main__":
    folder = Path(sys.argv[1] if len(sys.argv) > 1 else "ezdxf-plans")
    folder.mkdir(parents=True, exist_ok=True)
    for plan in all_plans():
        for binary in (False, True):
            print(plan.save(folder, binary))
