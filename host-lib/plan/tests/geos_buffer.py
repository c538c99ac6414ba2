"""GEOS's buffer (through shapely) for the recompensation property test (`plan_recompensation`):
one JSON request a line on stdin, one answer a line on stdout, until stdin closes.

Request: {"rings": [[[x, y], ...], ...], "d": mm} -- a polygon's outline, then its holes.
Answer: {"rings": [[[x, y], ...], ...]} -- the buffered polygon's outline, then its holes (one
polygon: the test's shapes stay in one piece), round joins, GEOS's default 8 segments a quarter circle (a
chord lies within 4.8e-3 of the radius inside its arc: 1.4 µm at 0.3 mm; the test allows for it).
"""

import json
import sys

import shapely

QUAD_SEGS = 8

for line in sys.stdin:
    request = json.loads(line)
    polygon = shapely.Polygon(request["rings"][0], request["rings"][1:])
    grown = shapely.buffer(polygon, request["d"], quad_segs=QUAD_SEGS, join_style="round")
    if grown.geom_type != "Polygon":
        answer = {"error": f"the buffer is a {grown.geom_type}"}
    else:
        rings = [grown.exterior, *grown.interiors]
        answer = {"rings": [[list(p) for p in r.coords] for r in rings]}
    print(json.dumps(answer), flush=True)
