"""Geofence files: QGroundControl's ``.plan`` ``geoFence`` and GeoJSON, read, written, and
turned into the planner's :class:`~uav_comm_planner.core.zones.Zones`.

A :class:`GeoFence` holds a fence as ground stations and autopilots hold it, on WGS84:
polygons (vertices latitude, longitude in degrees) and circles (centre latitude, longitude,
radius metres), each an inclusion (stay inside) or an exclusion (stay out). It is read from

- a QGroundControl ``.plan`` file's ``geoFence`` section (version 2: ``polygons`` of
  ``{"inclusion": bool, "polygon": [[lat, lon], ...]}`` and ``circles`` of
  ``{"inclusion": bool, "circle": {"center": [lat, lon], "radius": metres}}``), or
- a GeoJSON FeatureCollection (``.geojson`` or ``.json``) whose features carry the property
  ``"fence": "inclusion"`` or ``"fence": "exclusion"``: a ``Polygon`` (one ring, longitude
  first as GeoJSON orders it, closed or not) or a ``Point`` with ``"radius_m"`` (a circle).

:meth:`GeoFence.zones` anchors it at home (:mod:`.geodesy`): the one inclusion polygon is the
operating area; an inclusion circle becomes the regular polygon of
:data:`CIRCLE_SIDES` sides inscribed in it (staying inside the polygon keeps inside the
circle); exclusions are keep-out polygons and circles. A fence with more than one inclusion
zone is refused: the planner takes one operating area. :func:`fence_from_zones` goes back, and
:meth:`GeoFence.plan_section` is the ``geoFence`` a ``.plan`` file carries. Every bad file is a
:class:`~uav_comm_planner.errors.FenceFileError` naming the file and the place.
"""

from __future__ import annotations

from dataclasses import dataclass
import json
import math
import os
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from uav_comm_planner.core.zones import (crossing_message, KeepOutCircle, KeepOutPolygon,
                                         MAX_POLYGON_VERTICES, MAX_TOTAL_VERTICES,
                                         OperatingArea, Zones)
from uav_comm_planner.errors import FenceFileError, InvalidScenarioError, SelfCrossingError
from uav_comm_planner.files import read_json_file
from uav_comm_planner.vehicle.geodesy import enu_to_geodetic, geodetic_to_plane, Home

#: Sides of the polygon inscribed in an inclusion circle (its edges stay within
#: r (1 - cos(pi / 64)), 0.12 % of the radius, of the circle).
CIRCLE_SIDES = 64
#: A fence file larger than this is refused before it is read.
MAX_FENCE_FILE_BYTES = 16 * 1024 * 1024
#: Zones a fence may hold (each polygon vertex and each circle is one MAVLink fence item).
MAX_FENCE_ZONES = 100
#: Degrees are written with this many decimals (1e-8 degree, about 1 mm), as .plan missions.
DEGREE_DECIMALS = 8
FENCE_PROPERTY = 'fence'
RADIUS_PROPERTY = 'radius_m'
GEOJSON_SUFFIXES = ('.geojson', '.json')
#: Zones farther from home than this are refused (straight-line distance on the ground). The
#: planning frame is the tangent plane at home, each place mapped along its ellipsoid normal:
#: at a distance d its lengths differ from the ground's by up to (d / R)^2, 6.2e-5 at 50 km (3
#: mm over a 50 m clearance, 12 cm over a 2 km leg), the plane lies d^2 / 2R (196 m) above the
#: ground there and the normals tilt by d / R (0.45 degree). Beyond that the plane stops
#: meaning the ground, and at the antipode every place maps to home.
MAX_FENCE_DISTANCE_M = 50e3
#: A fence edge is straight in latitude and longitude, as ArduPilot and PX4 draw it, which is
#: curved in the planning frame (a parallel bends by tan(latitude) / R: 10.9 m off its chord
#: over 23 km at latitude 47). Edges are cut at points along that line until each piece's chord
#: is within this of it, so that the margin is kept from the edge the autopilot draws: a
#: millimetre, the size of the solver's cushion (``ZONE_CUSHION_M``), so that no planned point
#: comes inside the margin (at 1 cm, points came 6 mm inside it on a 23 km field).
EDGE_CHORD_TOLERANCE_M = 0.001


@dataclass(frozen=True)
class FencePolygon:
    """A polygon of the fence: vertices (K, 2) latitude, longitude degrees, not closed."""

    inclusion: bool
    vertices_deg: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class FenceCircle:
    """A circle of the fence: centre latitude, longitude degrees, radius metres."""

    inclusion: bool
    center_deg: tuple[float, float]
    radius_m: float


@dataclass(frozen=True)
class GeoFence:
    """A geofence on WGS84: its polygons and circles, inclusions and exclusions."""

    polygons: tuple[FencePolygon, ...] = ()
    circles: tuple[FenceCircle, ...] = ()

    @property
    def empty(self) -> bool:
        return not self.polygons and not self.circles

    def zones(self, home: Home, *, margin_m: float = Zones.margin_m) -> Zones:
        """The fence in the planning frame anchored at ``home``, as :class:`Zones` keeping
        ``margin_m`` from every edge. Raises InvalidScenarioError for a zone that is not
        one (a polygon that crosses itself, a radius <= 0) or a second inclusion zone."""
        inclusions = [z for z in (*self.polygons, *self.circles) if z.inclusion]
        if len(inclusions) > 1:
            raise InvalidScenarioError(
                f'the fence has {len(inclusions)} inclusion zones; the planner takes one '
                f'operating area: keep one inclusion polygon or circle')
        given = sum(len(polygon.vertices_deg) for polygon in self.polygons)
        if given > MAX_TOTAL_VERTICES:   # counted before any polygon is built and checked
            raise InvalidScenarioError(
                f'the fence has {given} polygon vertices in all, more than '
                f'{MAX_TOTAL_VERTICES}: simplify it')
        area = None
        keep_out: list = []
        for index, polygon in enumerate(self.polygons):
            what = f'polygon {index + 1}'
            vertices, edge = _edges_as_drawn(what, polygon.vertices_deg, home)
            kind = OperatingArea if polygon.inclusion else KeepOutPolygon
            zone = _zone(what, kind, vertices, (home, polygon, index), edge=edge)
            if polygon.inclusion:
                area = zone
            else:
                keep_out.append(zone)
        for index, circle in enumerate(self.circles):
            what = f'circle {index + 1}'
            center = _to_metres(what, np.array([circle.center_deg]), home,
                                reach_m=circle.radius_m)[0]
            if circle.inclusion:
                area = _zone(what, OperatingArea,
                             circle_ring(center, circle.radius_m, CIRCLE_SIDES),
                             (home, circle, index))
            else:
                keep_out.append(_zone(what, KeepOutCircle, tuple(center), circle.radius_m,
                                      (home, circle, index)))
        return Zones(area, tuple(keep_out), margin_m)

    def plan_section(self) -> dict:
        """The ``geoFence`` object of a QGroundControl .plan file (version 2)."""
        return {
            'circles': [{'circle': {'center': list(c.center_deg), 'radius': c.radius_m},
                         'inclusion': c.inclusion, 'version': 1} for c in self.circles],
            'polygons': [{'inclusion': p.inclusion, 'polygon': [list(v) for v in
                                                                p.vertices_deg],
                          'version': 1} for p in self.polygons],
            'version': 2,
        }


def circle_ring(center_m: ArrayLike, radius_m: float, sides: int) -> np.ndarray:
    """The (sides, 2) vertices of the regular polygon inscribed in a circle, counter-clockwise
    from east."""
    angles = 2 * np.pi * np.arange(sides) / sides
    return np.asarray(center_m, dtype=float) + radius_m * np.column_stack([np.cos(angles),
                                                                          np.sin(angles)])


#: Sides a keep-out circle is drawn with (figures, RViz markers).
DRAWN_CIRCLE_SIDES = 72


def zone_outlines(zones: Zones) -> list[tuple[str, np.ndarray]]:
    """Each zone's outline to draw, closed (first vertex repeated): ``('area', (K, 2))`` for
    the operating area, then ``('keep_out', (K, 2))`` for each keep-out zone, a circle as a
    polygon of :data:`DRAWN_CIRCLE_SIDES` sides; planning-frame metres."""
    outlines = []
    if zones.area is not None:
        outlines.append(('area', np.asarray(zones.area.vertices_m)))
    for zone in zones.keep_out:
        ring = (circle_ring(zone.center_m, zone.radius_m, DRAWN_CIRCLE_SIDES)
                if isinstance(zone, KeepOutCircle) else np.asarray(zone.vertices_m))
        outlines.append(('keep_out', ring))
    return [(kind, np.vstack([ring, ring[:1]])) for kind, ring in outlines]


def _zone(what: str, kind, *args, edge: np.ndarray | None = None):
    """``kind(*args)``, its refusal prefixed with the fence zone ``what``; for a polygon cut
    from the file's edges (``edge[k]``: the file's edge that the piece from vertex k lies on,
    :func:`_edges_as_drawn`), a crossing names the file's edges, not the pieces."""
    try:
        with np.errstate(all='ignore'):
            return kind(*args)
    except SelfCrossingError as exc:
        if edge is None:
            raise InvalidScenarioError(f'fence {what}: {exc}') from None
        first, second = (int(edge[k]) for k in exc.edges)
        raise InvalidScenarioError(f'fence {what}: ' + crossing_message(
            kind.what, first, second, ' (edge k from vertex k to the next)')) from None
    except InvalidScenarioError as exc:
        raise InvalidScenarioError(f'fence {what}: {exc}') from None


def _to_metres(what: str, degrees: np.ndarray, home: Home, *,
               reach_m: float = 0.0) -> np.ndarray:
    """Fence places (K, 2) latitude, longitude -> (K, 2) planning-frame metres, exactly as a
    mission's waypoints go back (:func:`geodetic_to_plane`); InvalidScenarioError for a place
    (plus ``reach_m``, a circle's radius) farther than :data:`MAX_FENCE_DISTANCE_M` from home."""
    east, north, distance = geodetic_to_plane(degrees[:, 0], degrees[:, 1], home)
    far = distance + reach_m
    worst = int(np.argmax(far))
    if not far[worst] <= MAX_FENCE_DISTANCE_M:
        latitude, longitude = degrees[worst]
        reach = f' with its radius of {reach_m:.6g} m' if reach_m else ''
        raise InvalidScenarioError(
            f'fence {what}: the point ({latitude:.8g}, {longitude:.8g}){reach} reaches '
            f'{far[worst] / 1000:.6g} km from home ({home.latitude_deg:.8g}, '
            f'{home.longitude_deg:.8g}), farther than the planning frame holds '
            f'({MAX_FENCE_DISTANCE_M / 1000:g} km): move home or the zone')
    return np.column_stack([east, north])


def _edges_as_drawn(what: str, vertices_deg: tuple[tuple[float, float], ...],
                    home: Home) -> tuple[np.ndarray, np.ndarray]:
    """A fence polygon's vertices in the planning frame (K, 2) metres, each edge, straight in
    latitude and longitude as the autopilot draws it, cut into pieces whose chords are within
    :data:`EDGE_CHORD_TOLERANCE_M` of it (the vertices given, then the cut points, in order),
    and for each vertex the index of the given edge its piece lies on (K,)."""
    degrees = np.array(vertices_deg, dtype=float)
    corners = _to_metres(what, degrees, home)
    jump = np.abs(np.roll(degrees[:, 1], -1) - degrees[:, 1])
    if (jump > 180.0).any():
        # ArduPilot's Polygon_outside and PX4 compare raw longitudes: such an edge is drawn
        # the long way round the Earth, through longitude 0, not across the antimeridian.
        first = int(np.argmax(jump > 180.0))
        raise InvalidScenarioError(
            f'fence {what}: its edge from vertex {first + 1} to vertex '
            f'{(first + 1) % len(degrees) + 1} crosses the antimeridian (longitude '
            f'{degrees[first, 1]:.8g} to {degrees[(first + 1) % len(degrees), 1]:.8g}), which '
            f'ArduPilot and PX4 draw the long way round the Earth: split the zone at 180 '
            f'degrees')
    # Longitudes relative to home's, so that an edge across the antimeridian is the short one.
    relative = np.column_stack([degrees[:, 0],
                                (degrees[:, 1] - home.longitude_deg + 180.0) % 360.0 - 180.0])
    start, end = relative, np.roll(relative, -1, axis=0)
    pieces = np.ones(len(degrees), dtype=int)
    for _ in range(8):
        deviation = _chord_deviation(start, end, pieces, home)
        short = deviation > EDGE_CHORD_TOLERANCE_M
        if not short.any():
            break
        # A parallel's offset from its chord grows with the square of the length.
        pieces = np.where(short, np.maximum(
            2 * pieces, np.ceil(pieces * np.sqrt(deviation / EDGE_CHORD_TOLERANCE_M) * 1.1)
        ).astype(int), pieces)
        if pieces.sum() > MAX_POLYGON_VERTICES:
            raise InvalidScenarioError(
                f'fence {what}: its edges, straight in latitude and longitude as the autopilot '
                f'draws them, need more than {MAX_POLYGON_VERTICES} vertices in the planning '
                f'frame to be kept within {EDGE_CHORD_TOLERANCE_M:g} m: give shorter edges')
    rows = []
    for index in range(len(degrees)):
        rows.append(corners[index:index + 1])
        if pieces[index] > 1:
            t = np.arange(1, pieces[index])[:, None] / pieces[index]
            cut = start[index] + t * (end[index] - start[index])
            rows.append(_to_metres(what, _absolute(cut, home), home))
    return np.vstack(rows), np.repeat(np.arange(len(degrees)), pieces)


def _absolute(relative: np.ndarray, home: Home) -> np.ndarray:
    longitude = (relative[:, 1] + home.longitude_deg + 180.0) % 360.0 - 180.0
    return np.column_stack([relative[:, 0], longitude])


def _chord_deviation(start: np.ndarray, end: np.ndarray, pieces: np.ndarray,
                     home: Home) -> np.ndarray:
    """The largest distance (m) of each edge start -> end (latitude, relative longitude), cut
    into ``pieces`` equal pieces in degrees, from its pieces' chords in the planning frame,
    sampled at 7 points a piece (every edge in one conversion)."""
    samples = np.linspace(0.0, 1.0, 9)
    edge = np.repeat(np.arange(len(start)), pieces)                  # each piece's edge
    piece = np.arange(len(edge)) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    t = (piece[:, None] + samples[None, :]) / pieces[edge][:, None]  # (P, 9)
    along = start[edge][:, None] + t[..., None] * (end[edge] - start[edge])[:, None]
    east, north, _ = geodetic_to_plane(*_absolute(along.reshape(-1, 2), home).T, home)
    points = np.column_stack([east, north]).reshape(len(edge), len(samples), 2)
    a, b = points[:, :1], points[:, -1:]
    chord = b - a
    length = np.linalg.norm(chord, axis=2)
    cross = np.abs(chord[..., 0] * (points[..., 1] - a[..., 1])
                   - chord[..., 1] * (points[..., 0] - a[..., 0]))
    offset = (cross / np.where(length > 0, length, 1.0)).max(axis=1)
    worst = np.zeros(len(start))
    np.maximum.at(worst, edge, offset)
    return worst


def _to_degrees(points_m: np.ndarray, home: Home) -> tuple[tuple[float, float], ...]:
    farthest = float(np.max(np.linalg.norm(points_m, axis=1)))
    if farthest > MAX_FENCE_DISTANCE_M:
        raise InvalidScenarioError(
            f'a zone reaches {farthest:.6g} m from home, farther than a fence goes '
            f'({MAX_FENCE_DISTANCE_M:g} m): give the zones in metres from home')
    latitude, longitude, _ = enu_to_geodetic(points_m[:, 0], points_m[:, 1], 0.0, home)
    return tuple((round(float(a), DEGREE_DECIMALS), round(float(b), DEGREE_DECIMALS))
                 for a, b in zip(np.atleast_1d(latitude), np.atleast_1d(longitude)))


def _read_from(zone, home: Home) -> tuple[FencePolygon | FenceCircle, int] | None:
    """The fence zone ``zone`` was read from at ``home`` and its place among the file's
    polygons or circles (None: made in metres, or read at another home)."""
    source = getattr(zone, 'source', None)
    if isinstance(source, tuple) and len(source) == 3 and source[0] == home and isinstance(
            source[1], (FencePolygon, FenceCircle)):
        return source[1], source[2]
    return None


def fence_from_zones(zones: Zones, home: Home) -> GeoFence:
    """The geofence of ``zones`` anchored at ``home``: the operating area an inclusion polygon,
    the keep-out zones exclusion polygons and circles (the margin is the planner's own and
    stays out of the fence). Zones read from a fence file at ``home`` are written as they were
    read (the same latitudes and longitudes, an inclusion circle a circle, in the file's
    order), not converted back from the planning frame."""
    polygons: list[tuple[float, FencePolygon]] = []
    circles: list[tuple[float, FenceCircle]] = []
    zones_in_order = [(z, False) for z in zones.keep_out]
    if zones.area is not None:
        zones_in_order.insert(0, (zones.area, True))
    read = [_read_from(zone, home) for zone, _ in zones_in_order]
    every_read = all(found is not None for found in read)
    for (zone, inclusion), found in zip(zones_in_order, read):
        # The file's order when every zone came from it; else the zones' own.
        place = found[1] if every_read else len(polygons) + len(circles)
        if found is not None and isinstance(found[0], FencePolygon):
            polygons.append((place, found[0]))
        elif found is not None:
            circles.append((place, found[0]))
        elif isinstance(zone, KeepOutCircle):
            center = _to_degrees(np.array([zone.center_m]), home)[0]
            circles.append((place, FenceCircle(False, center, zone.radius_m)))
        else:
            polygons.append((place, FencePolygon(
                inclusion, _to_degrees(np.asarray(zone.vertices_m), home))))
    return GeoFence(tuple(p for _, p in sorted(polygons, key=lambda item: item[0])),
                    tuple(c for _, c in sorted(circles, key=lambda item: item[0])))


# Reading.

class _Place(Exception):
    """A bad value at a place in the file (``where``: e.g. "polygons[1].polygon[3]")."""

    def __init__(self, where: str, why: str) -> None:
        super().__init__(f'{where}: {why}')


def _latitude_longitude(value: object, where: str, *, lon_first: bool = False
                        ) -> tuple[float, float]:
    if (not isinstance(value, (list, tuple)) or len(value) < 2
            or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value)):
        order = '[longitude, latitude]' if lon_first else '[latitude, longitude]'
        raise _Place(where, f'must be {order} in degrees, got {_short(value)}')
    latitude, longitude = (value[1], value[0]) if lon_first else (value[0], value[1])
    try:
        latitude, longitude = float(latitude), float(longitude)
    except OverflowError:
        raise _Place(where, f'{_short(value)} is out of range for degrees') from None
    if not (math.isfinite(latitude) and abs(latitude) <= 90.0):
        raise _Place(where, f'latitude {latitude!r} is not in [-90, 90] degrees')
    if not (math.isfinite(longitude) and abs(longitude) <= 180.0):
        raise _Place(where, f'longitude {longitude!r} is not in [-180, 180] degrees')
    return latitude, longitude


def _ring(points: object, where: str, *, lon_first: bool = False
          ) -> tuple[tuple[float, float], ...]:
    if not isinstance(points, list):
        raise _Place(where, f'must be a list of vertices, got {_short(points)}')
    if len(points) > MAX_POLYGON_VERTICES + 1:
        raise _Place(where, f'has {len(points)} vertices, more than {MAX_POLYGON_VERTICES}')
    vertices = [_latitude_longitude(p, f'{where}[{i}]', lon_first=lon_first)
                for i, p in enumerate(points)]
    if len(vertices) > 1 and vertices[0] == vertices[-1]:
        vertices = vertices[:-1]  # a closed ring (GeoJSON's rule) repeats its first vertex
    if len(vertices) < 3:
        raise _Place(where, f'has {len(vertices)} distinct vertices; a polygon needs 3')
    _no_repeated_vertex(vertices, where)
    return tuple(vertices)


def _no_repeated_vertex(vertices: list[tuple[float, float]], where: str) -> None:
    """Refuse a vertex given twice in a row (the closing repeat aside): its edge has no
    length, so it has no side to keep the margin from; dropping it would write back a fence
    other than the one read."""
    for i, (this, following) in enumerate(zip(vertices, vertices[1:] + vertices[:1])):
        if this == following:
            raise _Place(where, f'vertices {i} and {(i + 1) % len(vertices)} are the same '
                                f'place {this}: remove one')


def _radius(value: object, where: str) -> float:
    given = value
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 1000:
        value = math.inf   # beyond a double: refused below like any infinite radius
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            math.isfinite(value) and value > 0):
        raise _Place(where, f'must be a positive number of metres, got {_short(given)}')
    return float(value)


def _inclusion(value: object, where: str) -> bool:
    if not isinstance(value, bool):
        raise _Place(where, f'must be true or false, got {_short(value)}')
    return value


def _member(entry: object, key: str, where: str) -> object:
    if not isinstance(entry, dict):
        raise _Place(where, f'must be an object, got {_short(entry)}')
    if key not in entry:
        raise _Place(where, f'has no "{key}"')
    return entry[key]


def _list(value: object, where: str) -> list:
    if not isinstance(value, list):
        raise _Place(where, f'must be a list, got {_short(value)}')
    if len(value) > MAX_FENCE_ZONES:
        raise _Place(where, f'holds {len(value)} zones, more than {MAX_FENCE_ZONES}')
    return value


def plan_fence(document: object) -> GeoFence:
    """The geofence of a parsed .plan document (its ``geoFence``; none: an empty fence)."""
    if not isinstance(document, dict):
        raise _Place('the file', 'is not a JSON object')
    section = document.get('geoFence')
    if section is None:
        return GeoFence()
    if not isinstance(section, dict):
        raise _Place('geoFence', f'must be an object, got {_short(section)}')
    version = section.get('version', 2)
    if version != 2:
        raise _Place('geoFence.version', f'is {_short(version)}; version 2 is read')
    polygons = tuple(
        FencePolygon(_inclusion(_member(p, 'inclusion', f'geoFence.polygons[{i}]'),
                                f'geoFence.polygons[{i}].inclusion'),
                     _ring(_member(p, 'polygon', f'geoFence.polygons[{i}]'),
                           f'geoFence.polygons[{i}].polygon'))
        for i, p in enumerate(_list(section.get('polygons', []), 'geoFence.polygons')))
    circles = []
    for i, entry in enumerate(_list(section.get('circles', []), 'geoFence.circles')):
        where = f'geoFence.circles[{i}]'
        circle = _member(entry, 'circle', where)
        circles.append(FenceCircle(
            _inclusion(_member(entry, 'inclusion', where), f'{where}.inclusion'),
            _latitude_longitude(_member(circle, 'center', f'{where}.circle'),
                                f'{where}.circle.center'),
            _radius(_member(circle, 'radius', f'{where}.circle'), f'{where}.circle.radius')))
    return GeoFence(polygons, tuple(circles))


def geojson_fence(document: object) -> GeoFence:
    """The geofence of a parsed GeoJSON FeatureCollection (module docstring)."""
    if not isinstance(document, dict) or document.get('type') != 'FeatureCollection':
        raise _Place('the file', 'is not a GeoJSON FeatureCollection')
    polygons, circles = [], []
    for i, feature in enumerate(_list(_member(document, 'features', 'the FeatureCollection'),
                                      'features')):
        where = f'features[{i}]'
        properties = _member(feature, 'properties', where)
        kind = _member(properties, FENCE_PROPERTY, f'{where}.properties')
        if kind not in ('inclusion', 'exclusion'):
            raise _Place(f'{where}.properties.{FENCE_PROPERTY}',
                         f'must be "inclusion" or "exclusion", got {_short(kind)}')
        geometry = _member(feature, 'geometry', where)
        shape = _member(geometry, 'type', f'{where}.geometry')
        coordinates = _member(geometry, 'coordinates', f'{where}.geometry')
        if shape == 'Polygon':
            if not isinstance(coordinates, list) or len(coordinates) != 1:
                raise _Place(f'{where}.geometry.coordinates',
                             'must hold exactly one ring (a fence polygon has no holes)')
            polygons.append(FencePolygon(kind == 'inclusion', _ring(
                coordinates[0], f'{where}.geometry.coordinates[0]', lon_first=True)))
        elif shape == 'Point':
            circles.append(FenceCircle(
                kind == 'inclusion',
                _latitude_longitude(coordinates, f'{where}.geometry.coordinates',
                                    lon_first=True),
                _radius(_member(properties, RADIUS_PROPERTY, f'{where}.properties'),
                        f'{where}.properties.{RADIUS_PROPERTY}')))
        else:
            raise _Place(f'{where}.geometry.type',
                         f'is {_short(shape)}; a fence zone is a Polygon or a Point with '
                         f'"{RADIUS_PROPERTY}"')
    return GeoFence(tuple(polygons), tuple(circles))


def read_fence(path: str | os.PathLike) -> GeoFence:
    """The geofence in ``path``: a QGroundControl ``.plan`` (its ``geoFence``) or a GeoJSON
    FeatureCollection (``.geojson``, ``.json``). Raises FenceFileError, naming the file and
    the place, for a file that cannot be read or holds a bad zone."""
    target = Path(path)
    name = repr(str(target))
    suffix = target.suffix.lower()
    if suffix not in ('.plan', *GEOJSON_SUFFIXES):
        raise FenceFileError(f'unknown fence format {suffix or "(no extension)"!r} for {name}: '
                             f'use a QGroundControl .plan or a .geojson file')
    document = read_json_file(target, max_bytes=MAX_FENCE_FILE_BYTES, what='fence file',
                              error=FenceFileError)
    try:
        return plan_fence(document) if suffix == '.plan' else geojson_fence(document)
    except _Place as exc:
        raise FenceFileError(f'fence file {name}: {exc}') from None


def read_zones(path: str | os.PathLike, home: Home, *,
               margin_m: float = Zones.margin_m) -> Zones:
    """The zones of the fence file ``path`` anchored at ``home`` (:meth:`GeoFence.zones`);
    every refusal is a FenceFileError naming the file."""
    fence = read_fence(path)
    if fence.empty:
        raise FenceFileError(f'fence file {str(path)!r} holds no fence zone')
    try:
        return fence.zones(home, margin_m=margin_m)
    except InvalidScenarioError as exc:
        raise FenceFileError(f'fence file {str(path)!r}: {exc}') from None


def read_checked_fence(path: str | os.PathLike) -> GeoFence:
    """The geofence of ``path`` checked as :func:`read_zones` checks it (anchored at its own
    first point, which needs no home), for an upload that sends it as it is."""
    fence = read_fence(path)
    if fence.empty:
        raise FenceFileError(f'fence file {str(path)!r} holds no fence zone')
    first = fence.polygons[0].vertices_deg[0] if fence.polygons else fence.circles[0].center_deg
    try:
        fence.zones(Home(first[0], first[1], 0.0))
    except InvalidScenarioError as exc:
        raise FenceFileError(f'fence file {str(path)!r}: {exc}') from None
    return fence


def _short(value: object, limit: int = 60) -> str:
    text = json.dumps(value) if isinstance(value, (str, int, float, bool, type(None))) \
        else repr(value)
    return text if len(text) <= limit else text[:limit] + '...'


__all__ = ['CIRCLE_SIDES', 'DRAWN_CIRCLE_SIDES', 'FenceCircle', 'FencePolygon', 'GeoFence',
           'circle_ring', 'fence_from_zones', 'geojson_fence', 'plan_fence',
           'read_checked_fence', 'read_fence', 'read_zones', 'zone_outlines']
