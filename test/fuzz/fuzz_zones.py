"""Seeded fuzzing of zones and fence files (``make fuzz``).

Each case draws a hostile fence file (QGroundControl ``.plan`` or GeoJSON: places near home,
tens of kilometres away, at the antipode; wrong types, NaN, huge integers, broken structure,
self-crossing rings, many vertices) or a zones mapping of a scenario file, and checks that the
package answers with zones or a typed error (:class:`~uav_comm_planner.errors.PlannerError`):
zones it accepts lie within the planning frame's reach, a fence it accepts is written back as
it was read, paths round accepted zones keep their margin, nothing takes longer than
:data:`SLOW_S`; and the command line (``plan --fence``) answers with exit 0 or exit 2 and one
line on stderr. Prints the counts per kind and outcome and every failure; exits 1 if there was
one.

    python test/fuzz/fuzz_zones.py --cases 2000 --seed 1
"""

from __future__ import annotations

import json
import math
from pathlib import Path
import sys
import tempfile
import time
import traceback

from fuzz_report import fuzz_main, SeededFuzzer
import numpy as np

from uav_comm_planner import PlannerError
from uav_comm_planner.core.detour import shortest_path
from uav_comm_planner.core.zones import Zones
from uav_comm_planner.vehicle.fence import (fence_from_zones, MAX_FENCE_DISTANCE_M, read_fence,
                                            read_zones)
from uav_comm_planner.vehicle.geodesy import enu_to_geodetic, geodetic_to_plane, Home

#: A case slower than this (seconds) is a failure: every input is bounded before work.
SLOW_S = 20.0
HOMES = (Home(47.397742, 8.545594, 488.0), Home(-35.363262, 149.165237, 584.0),
         Home(0.0, 179.99, 0.0), Home(89.9, 0.0, 0.0))
JUNK = (None, True, 'x', '47.1', [], {}, [1], 10 ** 400, -10 ** 400, math.nan, math.inf,
        1e308, -0.0, 5e-324)


class Fuzzer(SeededFuzzer):

    # Draws.

    def junk(self) -> object:
        return self.rng.choice(JUNK)

    def place(self, home: Home, clean: bool = False) -> list:
        """A [latitude, longitude]: mostly near home, sometimes far, at the antipode, or junk
        (``clean``: within 20 km)."""
        kind = self.rng.random() * (0.6 if clean else 1.0)
        if kind < 0.65:
            reach = 10.0 ** self.rng.uniform(0.0, 4.6)     # 1 m .. 40 km
        elif kind < 0.85:
            reach = 10.0 ** self.rng.uniform(4.6, 5.3)     # 40 .. 200 km
        elif kind < 0.93:
            return [-home.latitude_deg + self.rng.uniform(-0.1, 0.1),
                    (home.longitude_deg + 360.0) % 360.0 - 180.0 + self.rng.uniform(-0.1, 0.1)]
        else:
            return [self.junk(), self.junk()] if self.rng.random() < 0.5 else self.junk()
        angle = self.rng.uniform(0.0, 2 * math.pi)
        latitude, longitude, _ = enu_to_geodetic(np.array([reach * math.cos(angle)]),
                                                 np.array([reach * math.sin(angle)]), 0.0, home)
        digits = self.rng.choice((5, 8, 12, 17))
        return [round(float(latitude[0]), digits), round(float(longitude[0]), digits)]

    def ring(self, home: Home, clean: bool = False) -> list:
        """A polygon's vertices: a regular ring round a place (sometimes shuffled, so that it
        crosses itself), or places drawn one by one (``clean``: a ring of 3 to 300 vertices
        within 20 km)."""
        count = self.rng.choice((3, 4, 5, 8, 40, 300) if clean else
                                (0, 2, 3, 4, 5, 8, 40, 300, 1001, 1200))
        if clean or self.rng.random() < 0.7:
            centre = self.place(home, clean)
            if not (isinstance(centre, list) and len(centre) == 2 and all(
                    isinstance(v, float) and math.isfinite(v) for v in centre)):
                return [centre] * max(count, 1)
            radius = 10.0 ** self.rng.uniform(0.0, 3.5 if clean else 4.3)
            east, north, _ = geodetic_to_plane(np.array([centre[0]]), np.array([centre[1]]),
                                               home)
            if not (np.isfinite(east).all() and np.isfinite(north).all()):
                return [centre] * max(count, 1)     # beyond the frame (the antipode)
            angles = np.linspace(0.0, 2 * math.pi, max(count, 1), endpoint=False)
            latitude, longitude, _ = enu_to_geodetic(east + radius * np.cos(angles),
                                                     north + radius * np.sin(angles), 0.0, home)
            vertices = [[float(a), float(b)] for a, b in zip(latitude, longitude)]
            if not clean and self.rng.random() < 0.15:
                self.rng.shuffle(vertices)
            if not clean and vertices and self.rng.random() < 0.1:
                repeated = self.rng.randrange(len(vertices))    # a vertex given twice in a row
                vertices.insert(repeated, vertices[repeated])
            return vertices
        return [self.place(home) for _ in range(count)]

    def fence_document(self, home: Home, geojson: bool) -> object:
        clean = self.rng.random() < 0.5    # a fence that may well be accepted
        polygons = [(not clean and self.rng.random() < 0.3, self.ring(home, clean))
                    for _ in range(self.rng.choice((1, 1, 2, 3) if clean else (0, 1, 1, 2, 3)))]
        circles = [(not clean and self.rng.random() < 0.2, self.place(home, clean),
                    10.0 ** self.rng.uniform(0, 3) if clean else self.rng.choice((
                        10.0 ** self.rng.uniform(-1, 5), 0, -5, 1e308, 10 ** 400, 'x', None)))
                   for _ in range(self.rng.choice((0, 0, 1, 2)))]
        if geojson:
            def feature(inclusion, geometry, **extra):
                return {'type': 'Feature', 'geometry': geometry, 'properties': {
                    'fence': 'inclusion' if inclusion else 'exclusion', **extra}}
            features = [feature(inc, {'type': 'Polygon', 'coordinates': [[
                v[::-1] if isinstance(v, list) else v for v in ring]]})
                for inc, ring in polygons]
            features += [feature(inc, {'type': 'Point', 'coordinates': centre[::-1] if
                                       isinstance(centre, list) else centre}, radius_m=radius)
                         for inc, centre, radius in circles]
            document = {'type': 'FeatureCollection', 'features': features}
        else:
            document = {'fileType': 'Plan', 'geoFence': {
                'version': 2,
                'polygons': [{'inclusion': inc, 'version': 1, 'polygon': ring}
                             for inc, ring in polygons],
                'circles': [{'inclusion': inc, 'version': 1,
                             'circle': {'center': centre, 'radius': radius}}
                            for inc, centre, radius in circles]}}
        if not clean and self.rng.random() < 0.2:     # broken structure
            document = self.rng.choice(([document], 5, None, {'geoFence': self.junk()},
                                        {'type': 'FeatureCollection', 'features': self.junk()}))
        return document

    def fence_file(self, folder: Path, home: Home) -> Path:
        geojson = self.rng.random() < 0.4
        path = folder / ('fence.geojson' if geojson else 'fence.plan')
        text = json.dumps(self.fence_document(home, geojson), default=str)
        path.write_text(text if self.rng.random() > 0.02 else text[:len(text) // 2])
        return path

    # Checks.

    def timed(self, kind: str, what: str, call):
        """Run ``call``: a PlannerError is a refusal, anything else (or a slow answer) a
        failure."""
        began = time.perf_counter()
        try:
            value = call()
        except PlannerError as exc:
            self.counts[(kind, f'refused {type(exc).__name__}')] += 1
            value = None
        except Exception as exc:  # noqa: B902 - any untyped exception is what we look for
            self.fail(kind, what, f'untyped {type(exc).__name__}: {exc}\n'
                      + ''.join(traceback.format_exc(limit=-3)))
            return None
        else:
            self.counts[(kind, 'ok')] += 1
        if time.perf_counter() - began > SLOW_S:
            self.fail(kind, what, f'took {time.perf_counter() - began:.1f} s')
        return value

    def check_zones(self, kind: str, what: str, zones: Zones, home: Home,
                    path: Path) -> None:
        reach = max([float(np.abs(z.vertices_m).max()) for z in (zones.area, *zones.keep_out)
                     if z is not None and hasattr(z, 'vertices_m')]
                    + [math.hypot(*z.center_m) + z.radius_m for z in zones.keep_out
                       if hasattr(z, 'radius_m')])
        if reach > MAX_FENCE_DISTANCE_M * 1.01:
            self.fail(kind, what, f'a zone {reach:.0f} m from home was accepted')
        written = fence_from_zones(zones, home)
        if written != read_fence(path):
            self.fail(kind, what, 'the fence written back differs from the file')
        start, goal = self.rng.uniform(-3000, 3000), self.rng.uniform(-3000, 3000)
        ends = np.array([[start, -goal], [goal, start]])
        if (zones.clearance(ends) >= zones.margin_m).all():
            route = self.timed(kind, what, lambda: shortest_path(zones, ends[0], ends[1]))
            if route is not None and zones.path_clearance(route) < zones.margin_m - 1e-6:
                self.fail(kind, what, 'a path round the zones enters their margin')

    # Cases.

    def case_fence(self) -> None:
        home = self.rng.choice(HOMES)
        with tempfile.TemporaryDirectory(dir=self.folder) as name:
            path = self.fence_file(Path(name), home)
            what = path.read_text()[:300]
            margin = self.rng.choice((0.0, 5.0, 10.0 ** self.rng.uniform(-2, 3)))
            zones = self.timed('fence', what, lambda: read_zones(path, home, margin_m=margin))
            if zones is not None:
                self.check_zones('fence', what, zones, home, path)

    def case_zones_mapping(self) -> None:
        data = {'keep_out': [self.rng.choice((
            {'center_m': [self.rng.uniform(-1e4, 1e4), self.junk()], 'radius_m': self.junk()},
            {'center_m': [self.rng.uniform(-1e4, 1e4), self.rng.uniform(-1e4, 1e4)],
             'radius_m': 10.0 ** self.rng.uniform(-3, 8)},
            {'vertices_m': [[self.rng.uniform(-1e3, 1e3), self.rng.uniform(-1e3, 1e3)]
                            for _ in range(self.rng.choice((2, 3, 5, 50)))]},
            {'vertices_m': [[self.junk(), 0], [1, 0], [0, 1]]},
            self.junk())) for _ in range(self.rng.choice((0, 1, 3, 10, 201, 300)))]}
        if self.rng.random() < 0.3:
            data['area'] = self.rng.choice(([[-5e3, -5e3], [5e3, -5e3], [5e3, 5e3]],
                                            [[1e308, 0], [0, 1e308], [0, 0]], self.junk()))
        if self.rng.random() < 0.3:
            data['margin_m'] = self.junk()
        self.timed('zones', repr(data)[:300], lambda: Zones.from_dict(data))

    def case_cli(self) -> None:
        home = self.rng.choice(HOMES)
        with tempfile.TemporaryDirectory(dir=self.folder) as name:
            folder = Path(name)
            path = self.fence_file(folder, home)
            out = folder / 'out'
            out.mkdir()
            argv = ['plan', '--case', 'I', '--slots', '20', '--horizon', '40',
                    f'--home={home.latitude_deg},{home.longitude_deg},{home.altitude_m}',
                    '--fence', str(path), '--mission', str(out / 'm.plan')]
            if self.rng.random() < 0.3:
                argv += ['--fence-margin', self.rng.choice(('0', '5', '-1', 'nan', '1e400'))]
            what = path.read_text()[:200]
            began = time.perf_counter()
            status, err = self.call_cli('cli', what, argv)
            if status is None:
                return
            self.judge_exit('cli', what, status, err)
            if status == 2 and any(out.iterdir()):
                self.fail('cli', what, 'a refusal left a file')
            if status == 0 and read_fence(out / 'm.plan') != read_fence(path):
                self.fail('cli', what, 'the mission carries another fence than the file')
            if time.perf_counter() - began > SLOW_S:
                self.fail('cli', what, f'took {time.perf_counter() - began:.1f} s')

    KINDS = (('case_fence', 0.55), ('case_zones_mapping', 0.3), ('case_cli', 0.15))


def main(argv: list[str] | None = None) -> int:
    return fuzz_main(Fuzzer, argv, __doc__, 'uav-fuzz-zones-')


if __name__ == '__main__':
    sys.exit(main())
