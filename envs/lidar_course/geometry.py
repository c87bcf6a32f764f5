"""Planar geometry of the lidar courses: polylines, corridor walls, distances (NumPy, no simulator).

Points are ``(x, y)`` in metres; a *segment* array has shape ``(n, 4)`` with rows ``(x0, y0, x1, y1)``.
"""

from __future__ import annotations

import math

import numpy as np

#: Angular step of the arcs that round a centre line's corners [rad] (about 7.5 degrees).
ARC_STEP = math.radians(7.5)


def polyline_segments(points: np.ndarray, closed: bool) -> np.ndarray:
    """
    Segments joining consecutive points of a polyline.

    :param points: ``(n, 2)`` vertices
    :param closed: Whether the last vertex joins the first
    :return: ``(n, 4)`` segments if ``closed``, else ``(n - 1, 4)``
    """
    if closed:  # np.roll's result, without its overhead (this runs several times per procedural layout)
        return np.concatenate([points, np.concatenate([points[1:], points[:1]])], axis=1)
    return np.concatenate([points[:-1], points[1:]], axis=1)


def segment_lengths(segments: np.ndarray) -> np.ndarray:
    """
    Lengths of segments.

    :param segments: ``(n, 4)`` segments
    :return: ``(n,)`` lengths
    """
    return np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])


def round_corners(points: np.ndarray, radius: float) -> np.ndarray:
    """
    Replace every corner of a closed polyline by a circular arc of the given radius.

    Each corner is cut back along both of its edges by ``radius / tan(half the turn's complement)`` and
    the two cut points are joined by an arc sampled every :data:`ARC_STEP`. Straight vertices (no turn)
    are dropped.

    :param points: ``(n, 2)`` vertices of a closed polyline (the last vertex joins the first)
    :param radius: Arc radius [m], ``> 0``
    :return: ``(m, 2)`` vertices of the rounded closed polyline
    :raises ValueError: if an edge is too short for the arcs at its two ends
    """
    # Every corner's numbers at once where they are element by element (the same bits as corner by corner), the
    # rest in Python floats: the arithmetic of a corner-by-corner loop over NumPy scalars, without their overhead.
    points = np.asarray(points, dtype=float)
    to_previous = points[np.arange(-1, len(points) - 1)] - points
    to_next = points[np.arange(1, len(points) + 1) % len(points)] - points
    lengths_previous = np.hypot(to_previous[:, 0], to_previous[:, 1])
    lengths_next = np.hypot(to_next[:, 0], to_next[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):  # corners skipped below (straight ones) may divide by 0
        u = to_previous / lengths_previous[:, None]
        w = to_next / lengths_next[:, None]
        halves = u + w
        bisectors = (halves / np.hypot(halves[:, 0], halves[:, 1])[:, None]).tolist()
    # Each arc: (centre x, centre y, first angle, sweep, samples).
    arcs: list[tuple[float, float, float, float, int]] = []
    lengths = zip(lengths_previous.tolist(), lengths_next.tolist(), strict=True)
    rows = zip(points.tolist(), u.tolist(), w.tolist(), lengths, bisectors, strict=True)
    for i, (corner, (ux, uy), (wx, wy), (length_previous, length_next), (bx, by)) in enumerate(rows):
        # Interior angle between the two edges at this corner (np.dot: the same rounding as the loop's).
        cosine = float(np.dot(u[i], w[i]))
        cosine = -1.0 if cosine < -1.0 else 1.0 if cosine > 1.0 else cosine
        interior = math.acos(cosine)
        if math.pi - interior < 1e-9:
            continue  # collinear vertex: nothing to round
        cut = radius / math.tan(interior / 2.0)
        if cut > length_previous / 2.0 + 1e-9 or cut > length_next / 2.0 + 1e-9:
            raise ValueError(
                f"corner {i} at ({corner[0]:g}, {corner[1]:g}) needs {cut:.3g} m of each adjacent edge for an arc of "
                f"radius {radius:g} m, but its edges are {length_previous:.3g} m and {length_next:.3g} m long "
                "(each may give at most half its length)"
            )
        reach = radius / math.sin(interior / 2.0)
        cx, cy = corner[0] + bx * reach, corner[1] + by * reach
        angle_start = math.atan2(corner[1] + uy * cut - cy, corner[0] + ux * cut - cx)
        angle_end = math.atan2(corner[1] + wy * cut - cy, corner[0] + wx * cut - cx)
        sweep = (angle_end - angle_start + math.pi) % (2.0 * math.pi) - math.pi
        arcs.append((cx, cy, angle_start, sweep, max(2, math.ceil(abs(sweep) / ARC_STEP) + 1)))
    if not arcs:
        raise ValueError("need at least one array to concatenate")  # as np.vstack of no arcs
    return _arc_points(np.array(arcs), radius)


def _arc_points(arcs: np.ndarray, radius: float) -> np.ndarray:
    # The points of arcs (rows: centre x, centre y, first angle, sweep, samples), all at once, with the numbers of
    # ``first angle + np.linspace(0.0, sweep, samples)`` (its steps ``i * (sweep / (samples - 1))``, its last
    # point the sweep itself).
    counts = arcs[:, 4].astype(np.int64)
    ends = np.cumsum(counts)
    steps = arcs[:, 3] / (counts - 1)
    if np.any(steps == 0.0):  # linspace's other arithmetic (a zero or subnormal step): arc by arc
        rows = zip(arcs[:, 2], arcs[:, 3], counts, strict=True)
        angles = np.concatenate([first + np.linspace(0.0, sweep, n) for first, sweep, n in rows])
    else:
        offsets = np.arange(ends[-1], dtype=float) - np.repeat(ends - counts, counts)
        offsets *= np.repeat(steps, counts)
        offsets += 0.0
        offsets[ends - 1] = arcs[:, 3]
        angles = np.repeat(arcs[:, 2], counts) + offsets
    centres = np.repeat(arcs[:, :2], counts, axis=0)
    return centres + radius * np.column_stack([np.cos(angles), np.sin(angles)])


def offset_closed_polyline(points: np.ndarray, offset: float) -> np.ndarray:
    """
    Offset a closed polyline sideways, with mitred joints.

    :param points: ``(n, 2)`` vertices of a closed polyline
    :param offset: Signed distance [m]: positive to the left of the direction of travel, negative to the right
    :return: ``(n, 2)`` vertices of the offset polyline
    """
    directions = np.concatenate([points[1:], points[:1]]) - points
    directions /= np.hypot(directions[:, 0], directions[:, 1])[:, None]
    normals = np.column_stack([-directions[:, 1], directions[:, 0]])
    # At vertex i the incoming edge is i - 1 and the outgoing edge is i.
    incoming = np.concatenate([normals[-1:], normals[:-1]])
    miter = incoming + normals
    miter /= np.hypot(miter[:, 0], miter[:, 1])[:, None]
    scale = offset / np.einsum("ij,ij->i", miter, normals)
    return points + miter * scale[:, None]


def point_segment_distances(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """
    Euclidean distances from points to segments.

    :param points: ``(2,)`` point or ``(m, 2)`` points
    :param segments: ``(n, 4)`` segments
    :return: ``(n,)`` distances for one point, ``(m, n)`` for several
    """
    points = np.asarray(points, dtype=float)
    segments = np.asarray(segments, dtype=float)
    x0, y0, dx, dy, divisors = _segment_terms(segments)
    return _distances(points[..., 0, None] - x0, points[..., 1, None] - y0, dx, dy, divisors)


def _segment_terms(segments: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    # Start, direction and squared length (1 for a zero-length segment) of each segment.
    x0, y0 = segments[:, 0], segments[:, 1]
    dx, dy = segments[:, 2] - x0, segments[:, 3] - y0
    lengths_squared = dx * dx + dy * dy
    return x0, y0, dx, dy, np.where(lengths_squared > 0.0, lengths_squared, 1.0)


def _distances(x: np.ndarray, y: np.ndarray, dx: np.ndarray, dy: np.ndarray, divisors: np.ndarray) -> np.ndarray:
    # Distances from points at (x, y) relative to segments' starts to the segments, element by element (broadcast),
    # in place in x and y: the arithmetic of the (m, n, 2) form, without its temporaries. Every distance this
    # module gives goes through here, so that the same point and segment give the same bits, in any array shape.
    fraction = x * dx
    fraction += y * dy
    fraction /= divisors
    np.clip(fraction, 0.0, 1.0, out=fraction)
    x -= dx * fraction
    y -= dy * fraction
    return np.hypot(x, y, out=x)


def nearest_segment_distances(points: np.ndarray, segments: np.ndarray, reach: float) -> np.ndarray:
    """
    For each point, the distance to its nearest segment, computed only where it is at most ``reach``.

    The same numbers as ``point_segment_distances(points, segments).min(axis=1)`` (bit for bit) for every point
    with a segment within ``reach``, and a larger number (``inf`` or a distance over ``reach``) for the others; only
    the pairs of a point and a segment whose bounding box, widened by ``reach``, shares a cell of a grid half
    ``reach`` wide with the point are measured. On the centre line of a corridor against its walls, a few percent
    of all pairs.

    :param points: ``(m, 2)`` points, ``m >= 1``
    :param segments: ``(n, 4)`` segments, ``n >= 1``
    :param reach: Largest distance needed [m], ``> 0``
    :return: ``(m,)`` distances
    """
    pair_points, distances = _near_pairs(points, segments, reach)
    nearest = np.full(len(points), np.inf)
    np.minimum.at(nearest, pair_points, distances)
    return nearest


def nearest_segment_distance(points: np.ndarray, segments: np.ndarray, reach: float) -> float:
    """
    The smallest of :func:`nearest_segment_distances`, without the per-point minima: the distance from the points
    to the segments where it is at most ``reach`` (bit for bit that of the brute force), else a larger number.

    :param points: ``(m, 2)`` points, ``m >= 1``
    :param segments: ``(n, 4)`` segments, ``n >= 1``
    :param reach: Largest distance needed [m], ``> 0``
    """
    _, distances = _near_pairs(points, segments, reach)
    return float(distances.min()) if len(distances) else math.inf


def _near_pairs(points: np.ndarray, segments: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    # The pairs (point index, distance) of nearest_segment_distances: every pair within `reach`, and some others.
    points = np.asarray(points, dtype=float)
    segments = np.asarray(segments, dtype=float)
    # Conservative cells: a pair within `reach` always shares one, whatever the rounding of the cell indices. Cells
    # half as wide as `margin`: fewer pairs to measure (most of the time), for a few more cells per segment.
    margin = reach * (1.0 + 1e-6) + 1e-9
    cell = margin / 2.0
    origin = points.min(axis=0)
    cells = np.floor((points - origin) / cell).astype(np.int64)
    n_columns, n_rows = (int(value) + 1 for value in cells.max(axis=0))
    keys = cells[:, 0] * n_rows + cells[:, 1]
    order = np.argsort(keys, kind="stable")
    bounds = np.searchsorted(keys[order], np.arange(n_columns * n_rows + 1))
    # The cells each segment's widened bounding box covers, within the points' grid.
    low = np.floor((np.minimum(segments[:, :2], segments[:, 2:]) - margin - origin) / cell).astype(np.int64)
    high = np.floor((np.maximum(segments[:, :2], segments[:, 2:]) + margin - origin) / cell).astype(np.int64)
    low = np.maximum(low, 0)
    high = np.minimum(high, [n_columns - 1, n_rows - 1])
    spans = np.maximum(high - low + 1, 0)
    n_cells = spans[:, 0] * spans[:, 1]
    segment_of_cell = np.repeat(np.arange(len(segments)), n_cells)
    within = np.arange(len(segment_of_cell)) - np.repeat(np.cumsum(n_cells) - n_cells, n_cells)
    rows = spans[segment_of_cell, 1]
    cell_keys = (low[segment_of_cell, 0] + within // rows) * n_rows + low[segment_of_cell, 1] + within % rows
    # Every point of those cells against the segment.
    firsts, counts = bounds[cell_keys], bounds[cell_keys + 1] - bounds[cell_keys]
    pair_segments = np.repeat(segment_of_cell, counts)
    pair_points = order[np.arange(len(pair_segments)) - np.repeat(np.cumsum(counts) - counts - firsts, counts)]
    x0, y0, dx, dy, divisors = _segment_terms(segments)
    distances = _distances(
        points[pair_points, 0] - x0[pair_segments],
        points[pair_points, 1] - y0[pair_segments],
        dx[pair_segments],
        dy[pair_segments],
        divisors[pair_segments],
    )
    return pair_points, distances


def closest_segment(point: np.ndarray, segments: np.ndarray) -> tuple[int, float]:
    """
    The segment nearest to a point.

    :param point: ``(2,)`` point
    :param segments: ``(n, 4)`` segments, ``n >= 1``
    :return: index of the nearest segment and its distance
    """
    distances = point_segment_distances(point, segments)
    index = int(np.argmin(distances))
    return index, float(distances[index])


def point_in_polygon(point: np.ndarray, polygon: np.ndarray) -> bool:
    """
    Even-odd rule test of whether a point lies inside a closed polygon.

    :param point: ``(2,)`` point
    :param polygon: ``(n, 2)`` vertices (the last joins the first; a repeated first vertex is allowed)
    """
    x, y = float(point[0]), float(point[1])
    x0, y0 = polygon[:, 0], polygon[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    crosses = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return bool(np.count_nonzero(crosses & (x < x_cross)) % 2 == 1)


def sample_polyline(points: np.ndarray, spacing: float, closed: bool) -> np.ndarray:
    """
    Points along a polyline, at most ``spacing`` apart (the vertices included).

    :param points: ``(n, 2)`` vertices
    :param spacing: Maximum distance between consecutive samples [m], ``> 0``
    :param closed: Whether the last vertex joins the first
    :return: ``(m, 2)`` samples
    """
    segments = polyline_segments(points, closed)
    counts = [max(1, math.ceil(math.hypot(x1 - x0, y1 - y0) / spacing)) for x0, y0, x1, y1 in segments.tolist()]
    # Segment i's samples at fractions 0, 1/n_i, ..., (n_i - 1)/n_i of it, all segments at once.
    steps = np.arange(sum(counts)) - np.repeat(np.cumsum(counts) - counts, counts)
    fractions = (steps / np.repeat(counts, counts))[:, None]
    starts = np.repeat(segments[:, :2], counts, axis=0)
    samples = starts + np.repeat(segments[:, 2:] - segments[:, :2], counts, axis=0) * fractions
    return samples if closed else np.vstack([samples, points[-1:]])


class LoopProgress:
    """
    Distance travelled along a closed polyline (a corridor's centre line), from positions given one after another.

    Each position is projected on the nearest segment; :meth:`advance` walks from the last position's segment
    to its neighbours while they are nearer (a robot moves a few centimetres per step), so a step costs a few
    microseconds.

    :param loop: ``(n, 2)`` vertices of a closed polyline (the last joins the first)
    """

    def __init__(self, loop: np.ndarray):
        segments = polyline_segments(loop, closed=True)
        self._segment_array = segments
        self._segments = [tuple(row) for row in segments.tolist()]
        lengths = segment_lengths(segments)
        self._lengths = lengths.tolist()
        self._arc = np.concatenate([[0.0], np.cumsum(lengths)[:-1]]).tolist()
        #: Length of the loop [m].
        self.length = float(lengths.sum())
        self._index = 0
        self._position = 0.0

    def _project(self, index: int, x: float, y: float) -> tuple[float, float]:
        # (squared distance to segment `index`, arc length of the projection)
        x0, y0, x1, y1 = self._segments[index]
        dx, dy = x1 - x0, y1 - y0
        length_squared = dx * dx + dy * dy
        t = ((x - x0) * dx + (y - y0) * dy) / length_squared if length_squared > 0.0 else 0.0
        t = 0.0 if t < 0.0 else 1.0 if t > 1.0 else t
        ex, ey = x0 + t * dx - x, y0 + t * dy - y
        return ex * ex + ey * ey, self._arc[index] + t * self._lengths[index]

    def reset(self, x: float, y: float) -> float:
        """Locate a position on the whole loop; returns its arc length from the loop's first vertex [m]."""
        index, _ = closest_segment(np.array([x, y]), self._segment_array)
        self._index = index
        self._position = self._project(index, x, y)[1]
        return self._position

    def advance(self, x: float, y: float) -> float:
        """The signed distance along the loop from the last position to this one [m] (forward is positive)."""
        n = len(self._segments)
        best_index = self._index
        best_distance, best_position = self._project(best_index, x, y)
        # Walk to the nearest segment from the last one, forward then backward: a step moves a few centimetres.
        for direction in (1, -1):
            while True:
                index = (best_index + direction) % n
                distance, position = self._project(index, x, y)
                if distance >= best_distance:
                    break
                best_distance, best_index, best_position = distance, index, position
        delta = best_position - self._position
        # The shorter way round: crossing the loop's first vertex wraps the arc length.
        half = self.length / 2.0
        if delta > half:
            delta -= self.length
        elif delta < -half:
            delta += self.length
        self._index, self._position = best_index, best_position
        return delta
