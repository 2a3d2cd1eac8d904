"""Recorded trajectories (log replay): SUMO's FCD output or a columnar file, read into one table
(:mod:`irlsim.data.recording_read`), checked before any work and resampled to the simulation step.

Two formats (docs/guide/demonstrators.md, "Recordings"):

- SUMO's FCD output (``sumo --fcd-output``, ``.xml``, or ``.xml.gz`` as SUMO gzips it):
  ``<timestep time=..><vehicle id x y angle speed lane .../>``; SUMO's angle is degrees from north,
  clockwise, and becomes the ENU heading in radians.
- A columnar file (``.csv`` or ``.parquet``): one row per vehicle and time, columns ``id`` (text), ``t``
  [s], ``x``, ``y`` [m, the network's coordinates, the front bumper's centre as SUMO's; the centre of
  the vehicle's box with ``position`` 'centre' and a ``length`` column: :func:`to_front`], ``v`` [m/s],
  ``heading`` [rad, ENU: counter-clockwise from east; optional: without it, the direction of motion,
  :func:`headings_from_motion`]; ``lane`` (a SUMO lane id) optional, and
  ``length``, ``width`` [m] optional: the vehicle's size, one value per vehicle (the replay's vehicle
  type's where not given).

Checked, each refusal one line naming the file and the row or vehicle: missing columns, values that are not
finite, time not increasing within a vehicle, gaps longer than ``max_gap`` (or time in milliseconds),
headings that look like degrees or part from the direction of motion, speeds that look like km/h (3.6
times what the positions travel), points off the network or a recording in another network's
coordinates, sizes that are not one vehicle's in metres. Grouping by vehicle is a stable sort and a split
(no loop over rows); each vehicle is then resampled to the step by linear interpolation (heading
unwrapped).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.data.matching import LaneSamples, lane_routes, lane_samples, match_routes
from irlsim.data.recording_as import FRONT, NETWORK, check_position, to_front, to_network, typed
from irlsim.data.recording_read import Rows, read_rows
from irlsim.errors import IrlsimError
from irlsim.road import wrap_angle
from irlsim.road.angles import atan2
from irlsim.sim.vehicle_types import VehicleType

#: [m] the sizes a road vehicle has (bicycle to long truck); outside them a unit mistake (cm, feet)
SIZE_RANGE = {"length": (1.0, 30.0), "width": (0.5, 4.0)}
#: [m] how much a vehicle's recorded size may vary between its rows (a dataset's rounding)
SIZE_TOL = 0.01
#: [s] the longest time between two rows of one vehicle
MAX_GAP = 1.0
#: [m] a point farther than this from every lane of the network is off the network
OFF_NETWORK_M = 5.0
#: share of a recording's points off the network above which it is another network's coordinates
FOREIGN_SHARE = 0.5
#: recorded speed / speed of the displacement in this band: km/h given for m/s (3.6)
KMH_BAND = (2.6, 5.0)
#: the same ratio of a recording whose time is in milliseconds (a thousand), with a margin for rounding
MS_BAND = (300.0, 3000.0)
#: [m/s] a vehicle slower than this (displacement over time) is not tested for km/h
KMH_MIN_SPEED = 2.0
#: [s] the direction a vehicle moves in is read between its rows about this far apart in time, and
#: [m] only where they lie this far apart or more (its heading is checked against it): a standing car's
#: position noise (a tracker's, a GPS's: 0.5 m apart row to row is common) points anywhere
HEADING_BASE_S = 1.0
HEADING_MIN_STEP = 2.0
#: [rad] the median difference between heading and direction of motion above which the headings are in
#: another convention
HEADING_MAX_DIFF = math.radians(45.0)


@dataclass(frozen=True)
class Recording:
    """Every vehicle's track at the simulation step: vehicle ``k`` owns rows ``start[k]:start[k + 1]``,
    at times ``t0[k] + j * step``. ``edges[k]``: the network edges it drove, in order, a connected route
    a passenger car may drive (internal ones left out; from its recorded lanes, else its positions;
    empty where there is none, ``unrouted[k]`` saying why)."""

    path: Path
    sha256: str
    step: float
    ids: tuple[str, ...]
    start: np.ndarray  # [V + 1]
    t0: np.ndarray  # [V] [s]
    x: np.ndarray  # [R]
    y: np.ndarray
    v: np.ndarray
    heading: np.ndarray
    edges: tuple[tuple[str, ...], ...]
    #: per vehicle, why it drove no connected route a car may drive ('' where it did)
    unrouted: tuple[str, ...] = ()
    #: [V] [m] per vehicle, its recorded length and width, where the recording has them
    size: dict[str, np.ndarray] = field(default_factory=dict)
    #: [s] the recording's own sampling interval (the median time between a vehicle's rows; 0: not known)
    interval: float = 0.0
    #: per vehicle, SUMO's class of its type where the recording's types were read (``ReadAs``); empty: not
    vclass: tuple[str, ...] = ()

    def track(self, vid: str) -> dict[str, np.ndarray]:
        """One vehicle's arrays t, x, y, v, heading at the step."""
        k = self.ids.index(vid)
        a, b = int(self.start[k]), int(self.start[k + 1])
        t = self.t0[k] + self.step * np.arange(b - a)
        return {"t": t, "x": self.x[a:b], "y": self.y[a:b], "v": self.v[a:b], "heading": self.heading[a:b]}

    def duration(self) -> np.ndarray:
        """[V] [s] each vehicle's recorded time."""
        return (np.diff(self.start) - 1) * self.step


def check_rows(rows: Rows, max_gap: float = MAX_GAP) -> tuple[np.ndarray, np.ndarray]:
    """Refuse, in one line, rows that are not a recording of vehicles over time; returns (the stable
    order grouping the rows by vehicle, the group starts in it)."""
    p, n = rows.path, len(rows.t)
    if n == 0:
        raise IrlsimError(f"recording {p} holds no rows: record at least one vehicle")
    given = [rows.t, rows.x, rows.y, rows.v] + ([] if rows.no_heading else [rows.heading])
    bad = np.flatnonzero(~np.isfinite(np.stack(given)).all(axis=0))
    if len(bad):
        raise IrlsimError(
            f"{rows.where(bad[0])}: t, x, y, v and heading must be numbers: fix or drop the row"
        )
    if not rows.fcd and not rows.no_heading:
        deg = np.flatnonzero(np.abs(rows.heading) > 2 * math.pi + 1e-6)
        if len(deg):
            raise IrlsimError(
                f"{rows.where(deg[0])}: heading {rows.heading[deg[0]]:g} is beyond 2 pi: headings are "
                "radians (ENU, counter-clockwise from east), these look like degrees: convert them"
            )
    nameless = np.flatnonzero(np.char.strip(rows.id.astype(str)) == "")
    if len(nameless):
        raise IrlsimError(
            f"{rows.where(nameless[0])}: the row has no vehicle id (an empty cell): give every row the id "
            "of the vehicle it records, or drop the row"
        )
    if (rows.v < 0).any():
        i = int(np.flatnonzero(rows.v < 0)[0])
        raise IrlsimError(
            f"{rows.where(i)}: speed {rows.v[i]:g} is negative: give the speed's magnitude [m/s]"
        )
    order = np.argsort(rows.id, kind="stable")
    ids = rows.id[order]
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    t = rows.t[order]
    same = np.r_[False, ids[1:] == ids[:-1]]  # row i continues the vehicle of row i - 1
    dt = np.r_[np.inf, np.diff(t)]
    back = np.flatnonzero(same & (dt <= 0))
    if len(back):
        i = back[0]
        raise IrlsimError(
            f"{rows.where(order[i])}: vehicle {ids[i]} at t = {t[i]:g} s after t = {t[i - 1]:g} s: time must "
            "increase within each vehicle: sort the rows by time (and drop duplicates)"
        )
    gap = np.flatnonzero(same & (dt > max_gap))
    if len(gap) and _time_in_milliseconds(rows, order, starts):
        raise IrlsimError(
            f"{rows.path}: its speeds travel about a thousand times the distance its positions do, and a "
            f"vehicle's rows are {np.median(dt[same]):g} apart: t looks like milliseconds, give seconds "
            "(divide by 1000)"
        )
    if len(gap) and float(np.median(dt[same])) > max_gap:  # not a gap: the recording's rate
        raise IrlsimError(
            f"{p}: a vehicle's rows are {np.median(dt[same]):g} s apart (the median), more than the "
            f"{max_gap:g} s between rows irlsim interpolates over: record at least every {max_gap:g} s "
            "(sumo --device.fcd.period)"
        )
    if len(gap):
        i = gap[0]
        raise IrlsimError(
            f"{rows.where(order[i])}: vehicle {ids[i]} has a gap of {dt[i]:g} s after t = {t[i - 1]:g} s, "
            f"more than the {max_gap:g} s allowed: give each stretch its own vehicle id, or fill the gap"
        )
    _check_speed_units(rows, order, starts)
    if not rows.no_heading:
        _check_heading(rows, order, starts)
    _check_sizes(rows, order, starts)
    return order, starts


def _vehicles(t: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, float | None]:
    """Per row of the rows grouped by vehicle (times ``t``, groups starting at ``starts``) its vehicle's
    index, and the median time between a vehicle's consecutive rows (None: no vehicle has two)."""
    vehicle = np.repeat(np.arange(len(starts)), np.diff(np.r_[starts, len(t)]))
    same = vehicle[1:] == vehicle[:-1]
    return vehicle, float(np.median(np.diff(t)[same])) if same.any() else None


def _check_heading(rows: Rows, order: np.ndarray, starts: np.ndarray) -> None:
    """The headings against the direction the positions move (between a vehicle's rows about
    ``HEADING_BASE_S`` apart, at least ``HEADING_MIN_STEP`` apart in space; the heading halfway): a median
    difference over ``HEADING_MAX_DIFF`` is another angle convention (SUMO's angle from north, clockwise,
    or x and y swapped), which would leave every cycle without a demonstration."""
    x, y, h = rows.x[order], rows.y[order], rows.heading[order]
    vehicle, step = _vehicles(rows.t[order], starts)
    if step is None:
        return
    k = max(1, int(round(HEADING_BASE_S / step)))
    if len(x) <= k:
        return
    dx, dy = x[k:] - x[:-k], y[k:] - y[:-k]
    moved = (vehicle[k:] == vehicle[:-k]) & (np.hypot(dx, dy) > HEADING_MIN_STEP)
    if not moved.any():
        return
    halfway = np.arctan2(np.sin(h[k:]) + np.sin(h[:-k]), np.cos(h[k:]) + np.cos(h[:-k]))
    diff = np.abs(wrap_angle(np.arctan2(dy, dx)[moved] - halfway[moved]))
    median = float(np.median(diff))
    if median > HEADING_MAX_DIFF:
        raise IrlsimError(
            f"{rows.path}: its headings differ from the direction its positions move in by "
            f"{math.degrees(median):.0f} degrees (the median over its moving rows): headings are radians, "
            "ENU, counter-clockwise from east (SUMO's angle is degrees from north, clockwise: heading = "
            "radians(90 - angle)), or x and y are swapped"
        )


def headings_from_motion(
    rows: Rows, order: np.ndarray, starts: np.ndarray, samples: LaneSamples
) -> np.ndarray:
    """[N] [rad] ENU, in file order: each row's heading, the direction a vehicle's positions move in
    between its rows about ``HEADING_BASE_S`` apart around it (a chord of length D, which a position noise
    of sigma turns by about 1.4 sigma / D), where they lie ``HEADING_MIN_STEP`` apart or
    more; held from the nearest such row of the vehicle where they do not (it stands or creeps); for a
    vehicle that never moves so far, the direction of the lane nearest its first position (``samples``:
    the network's lanes)."""
    x, y = rows.x[order], rows.y[order]
    n = len(x)
    vehicle, step = _vehicles(rows.t[order], starts)
    first, last = starts[vehicle], (np.r_[starts[1:], n] - 1)[vehicle]
    half = max(1, int(round(0.5 * HEADING_BASE_S / (step or HEADING_BASE_S))))
    i = np.arange(n)
    a, b = np.maximum(i - half, first), np.minimum(i + half, last)
    dx, dy = x[b] - x[a], y[b] - y[a]
    moved = np.hypot(dx, dy) >= HEADING_MIN_STEP
    head = np.asarray(atan2(dy, dx), dtype=np.float64)
    before = np.maximum.accumulate(np.where(moved, i, -1))  # the last moving row up to each row
    after = np.minimum.accumulate(np.where(moved, i, n)[::-1])[::-1]  # the next from each row
    src = np.where(before >= first, before, np.where(after <= last, after, -1))
    out = np.where(src >= 0, head[np.maximum(src, 0)], np.nan)
    still = np.flatnonzero(src[starts] < 0)  # vehicles that never move so far: a loop over them, few
    if len(still):
        ends = np.r_[starts[1:], n]
        for k in still:
            d2 = (samples.xy[:, 0] - x[starts[k]]) ** 2 + (samples.xy[:, 1] - y[starts[k]]) ** 2
            out[starts[k] : ends[k]] = samples.angle[int(np.argmin(d2))]
    heading = np.empty(n)
    heading[order] = out
    return heading


def _check_sizes(rows: Rows, order: np.ndarray, starts: np.ndarray) -> None:
    """The optional length and width: metres within ``SIZE_RANGE``, one value per vehicle."""
    for c, col in rows.size.items():
        lo, hi = SIZE_RANGE[c]
        bad = np.flatnonzero(~(np.isfinite(col) & (col >= lo) & (col <= hi)))
        if len(bad):
            i = bad[0]
            raise IrlsimError(
                f"{rows.where(i)}: {c} {col[i]:g} is not a vehicle's {c} in metres ({lo:g}-{hi:g} m): "
                "give metres (centimetres and feet are converted before)"
            )
        v = col[order]
        first = np.repeat(v[starts], np.diff(np.r_[starts, len(v)]))
        varies = np.flatnonzero(np.abs(v - first) > SIZE_TOL)
        if len(varies):
            i = varies[0]
            raise IrlsimError(
                f"{rows.where(order[i])}: vehicle {rows.id[order[i]]} has {c} {v[i]:g} m after "
                f"{first[i]:g} m: a vehicle has one {c}: give the same value in all its rows"
            )


def _travel_ratio(rows: Rows, order: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per vehicle: (the recorded speed integrated over time (trapezoids) over the distance its positions
    travel, that distance, the integrated one, whether it moves faster than ``KMH_MIN_SPEED``)."""
    x, y, t, v = rows.x[order], rows.y[order], rows.t[order], rows.v[order]
    step = np.r_[0.0, np.hypot(np.diff(x), np.diff(y))]
    step[starts] = 0.0
    dist = np.add.reduceat(step, starts)
    ends = np.r_[starts[1:], len(t)] - 1
    dur = t[ends] - t[starts]
    dtt = np.r_[0.0, np.diff(t)]
    dtt[starts] = 0.0
    vv = np.r_[0.0, 0.5 * (v[1:] + v[:-1])] * dtt
    travelled = np.add.reduceat(vv, starts)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = travelled / dist
        moving = (dur > 0) & (dist / np.where(dur > 0, dur, 1.0) > KMH_MIN_SPEED)
    return ratio, dist, travelled, moving


def _check_speed_units(rows: Rows, order: np.ndarray, starts: np.ndarray) -> None:
    """Per vehicle, the mean recorded speed against the speed of its displacement: km/h is 3.6 times."""
    ratio, dist, travelled, moving = _travel_ratio(rows, order, starts)
    bad = np.flatnonzero(moving & (ratio > KMH_BAND[0]) & (ratio < KMH_BAND[1]))
    if len(bad):
        k = bad[0]
        raise IrlsimError(
            f"{rows.path}: vehicle {rows.id[order[starts[k]]]}: its speeds travel {ratio[k]:.2f} times the "
            f"distance its positions do ({travelled[k]:.0f} m against {dist[k]:.0f} m): v looks like km/h, "
            "give m/s (divide by 3.6)"
        )


def _time_in_milliseconds(rows: Rows, order: np.ndarray, starts: np.ndarray) -> bool:
    """Most vehicles' speeds travel about a thousand times what their positions do: t in ms (a vehicle
    that moves is one that travels over 20 m: its speed over time would say nothing, time being off)."""
    ratio, dist, _, _ = _travel_ratio(rows, order, starts)
    far = dist > 20.0
    return bool(far.any()) and MS_BAND[0] < float(np.median(ratio[far])) < MS_BAND[1]


def check_on_network(
    rows: Rows, net: Any, bound: float = OFF_NETWORK_M, samples: LaneSamples | None = None
) -> None:
    """Refuse a recording whose points lie off ``net`` (a sumolib network): more than ``FOREIGN_SHARE``
    of them, another network's coordinates; else the first point farther than ``bound`` from every
    lane. Lanes are sampled every metre into a grid of cells marked within ``bound`` of a lane
    (``samples``: ``net``'s where the caller has them)."""
    cell = 1.0
    pts = (lane_samples(net) if samples is None else samples).xy  # every metre or closer, internal lanes too
    lo = pts.min(axis=0) - 2 * bound
    hi = pts.max(axis=0) + 2 * bound
    cell = max(cell, float(np.prod(hi - lo) / 2e7) ** 0.5)  # at most ~20 M cells
    shape = np.ceil((hi - lo) / cell).astype(int) + 1
    grid = np.zeros(shape, dtype=bool)
    r = int(math.ceil(bound / cell))
    ox, oy = np.meshgrid(np.arange(-r, r + 1), np.arange(-r, r + 1), indexing="ij")
    disk = (ox**2 + oy**2) * cell * cell <= bound * bound
    base = np.floor((pts - lo) / cell).astype(int)
    for dx, dy in zip(ox[disk], oy[disk], strict=True):  # over the disk's cells, not the points
        grid[np.clip(base[:, 0] + dx, 0, shape[0] - 1), np.clip(base[:, 1] + dy, 0, shape[1] - 1)] = True

    def near(x: np.ndarray, y: np.ndarray) -> np.ndarray:  # [N] bool: within ``bound`` of a lane
        q = np.floor((np.stack([x, y], axis=1) - lo) / cell).astype(int)
        inside = (q >= 0).all(axis=1) & (q < shape).all(axis=1)
        out = np.zeros(len(q), dtype=bool)
        out[inside] = grid[q[inside, 0], q[inside, 1]]
        return out

    on = near(rows.x, rows.y)
    off = np.flatnonzero(~on)
    if not len(off):
        return
    geo = bool((np.abs(rows.x) <= 180.0).all() and (np.abs(rows.y) <= 90.0).all())
    if len(off) > FOREIGN_SHARE * len(on) and geo:
        raise IrlsimError(
            f"recording {rows.path}: its points lie off this network and within x -180..180, y -90..90: "
            "longitude and latitude (as sumo --fcd-output.geo writes them): set demonstrator.coordinates = "
            "'geo' (SUMO places them through the network's projection), or record x and y in the network's "
            "coordinates (sumo's --fcd-output without .geo)"
        )
    offset = tuple(float(v) for v in net.getLocationOffset())
    if len(off) > FOREIGN_SHARE * len(on) and any(offset):
        if near(rows.x + offset[0], rows.y + offset[1]).mean() > 1.0 - FOREIGN_SHARE:
            raise IrlsimError(
                f"recording {rows.path}: its points lie on this network once its netOffset ({offset[0]:.2f}, "
                f"{offset[1]:.2f}) is added: the network's original projection (as sumo --fcd-output.utm "
                "writes it): set demonstrator.coordinates = 'utm' (the netOffset added), or record x and y "
                "in the network's coordinates (sumo's --fcd-output without .utm)"
            )
    if len(off) > FOREIGN_SHARE * len(on):
        raise IrlsimError(
            f"recording {rows.path}: {len(off) / len(on):.0%} of its points lie off this network (x "
            f"{rows.x.min():.0f}..{rows.x.max():.0f}, y {rows.y.min():.0f}..{rows.y.max():.0f} m against the "
            f"network's x {lo[0] + 2 * bound:.0f}..{hi[0] - 2 * bound:.0f}, y {lo[1] + 2 * bound:.0f}.."
            f"{hi[1] - 2 * bound:.0f} m): another network's coordinates: give the scenario it was recorded on"
        )
    i = off[0]
    n_off, n_all = len(np.unique(rows.id[off])), len(np.unique(rows.id))
    many, fix = "", ""
    if n_off > 1:  # several vehicles: perhaps another network whose lanes pass near many of its points
        many = f"; so are {len(off) / len(on):.0%} of the points, of {n_off} of its {n_all} vehicles"
        fix = ", or give the scenario the recording was made on"
    raise IrlsimError(
        f"{rows.where(i)}: vehicle {rows.id[i]} at t = {rows.t[i]:g} s, ({rows.x[i]:.1f}, {rows.y[i]:.1f}), "
        f"is off the network (over {bound:g} m from every lane{many}): drop the vehicle or fix its "
        f"coordinates{fix}"
    )


def resample(
    rows: Rows,
    order: np.ndarray,
    starts: np.ndarray,
    step: float,
    sha: str,
    routes: list[tuple[str, ...] | str] | None = None,
    vclass: np.ndarray | None = None,
) -> Recording:
    """Each vehicle at the times ``k * step`` inside its recorded span, by linear interpolation (the
    heading unwrapped, then wrapped); a vehicle shorter than one step keeps no row and is left out.
    ``routes``: per vehicle its route or why none (:mod:`irlsim.data.matching`); ``vclass``: per row its
    type's class (:func:`typed`), None where the types were not read."""
    bounds = np.r_[starts, len(order)]
    ids, start, t0s, parts, edges, unrouted = [], [0], [], [], [], []
    kept: list[int] = []  # the vehicles (groups) kept
    gaps = [np.diff(rows.t[order[a:b]]) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    gap = np.concatenate(gaps) if gaps else np.zeros(0)
    for g, (a, b) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):  # per vehicle, not per row
        idx = order[a:b]
        t = rows.t[idx]
        k0, k1 = math.ceil(t[0] / step - 1e-6), math.floor(t[-1] / step + 1e-6)
        if k1 < k0:
            continue
        tq = np.arange(k0, k1 + 1) * step
        head = np.unwrap(rows.heading[idx])
        cols = [np.interp(tq, t, c[idx]) for c in (rows.x, rows.y, rows.v)]
        parts.append(np.stack([*cols, np.asarray(wrap_angle(np.interp(tq, t, head)))]))
        ids.append(str(rows.id[idx[0]]))
        kept.append(a)
        start.append(start[-1] + len(tq))
        t0s.append(k0 * step)
        route = routes[g] if routes is not None else ()
        matched = route if isinstance(route, tuple) else ()
        edges.append(matched)
        unrouted.append(route if isinstance(route, str) else "")
    data = np.concatenate(parts, axis=1) if parts else np.zeros((4, 0))
    return Recording(
        path=rows.path,
        sha256=sha,
        step=step,
        ids=tuple(ids),
        start=np.array(start),
        t0=np.array(t0s),
        x=data[0],
        y=data[1],
        v=data[2],
        heading=data[3],
        edges=tuple(edges),
        unrouted=tuple(unrouted),
        size={c: col[order[kept]] for c, col in rows.size.items()},
        vclass=tuple(str(c) for c in vclass[order[kept]]) if vclass is not None else (),
        interval=float(np.median(gap[gap > 0])) if (gap > 0).any() else 0.0,
    )


def load_recording(
    path: str | Path,
    net: Any,
    step: float,
    max_gap: float = MAX_GAP,
    position: str = FRONT,
    types: Mapping[str, VehicleType] | None = None,
    coordinates: str = NETWORK,
    net_file: str | Path | None = None,
) -> Recording:
    """Read, check (one line before any work) and resample a recording on ``net`` (a sumolib network,
    read from ``net_file``); ``position``: the point of a vehicle its x, y give (:data:`POSITIONS`), read
    as the front bumper; ``types``: the vehicle types the recording names, as SUMO makes them
    (:func:`typed`), None: not read; ``coordinates``: what its x, y are (:func:`to_network`)."""
    rows = to_network(read_rows(path), coordinates, net, net_file)
    vclass = None
    if types is not None:
        rows, vclass = typed(rows, types)
    check_position(rows, position)
    order, starts = check_rows(rows, max_gap)
    samples = lane_samples(net)  # every lane sampled once: the network check, headings, matching
    check_on_network(rows, net, samples=samples)
    if rows.no_heading:
        rows = dataclasses.replace(rows, heading=headings_from_motion(rows, order, starts, samples))
    rows = to_front(rows, position)
    if rows.lane is not None:
        known = {ln.getID() for e in net.getEdges(withInternal=True) for ln in e.getLanes()}
        unknown = sorted(set(rows.lane.tolist()) - known)
        if unknown:
            raise IrlsimError(
                f"recording {rows.path}: lane {unknown[0]} is not a lane of this network: give the scenario "
                "it was recorded on (or drop the lane column)"
            )
    cols = {k: getattr(rows, k)[order] for k in ("t", "x", "y", "v", "heading")}
    bounds = np.r_[starts, len(order)]
    if rows.lane is None:  # each vehicle's route from its positions
        routes = match_routes(net, cols, bounds, OFF_NETWORK_M, samples)
    else:  # from its recorded lanes, made connected
        routes = lane_routes(net, rows.lane[order], cols, bounds)
    sha = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    return resample(rows, order, starts, step, sha, routes, vclass)
