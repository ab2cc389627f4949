#!/usr/bin/env python3
"""Deterministic generator of the SoftFoot-Q visual / collision-source meshes.

Usage::

    python generate_meshes.py [OUT_DIR]

``OUT_DIR`` defaults to the folder holding this script.  Five binary STL files are
written, in METRES, each in its URDF link frame at joint angle 0 (foot convention:
x forward, y left, z up).  The shapes are reconstructed from the published dimensions
of the SoftFoot-Q (Catalano et al., IEEE T-RO 38(1), 2022; public ROS description,
BSD-3) collected in ``shared/reference/softfoot_q.md``.  They are not the CAD parts:
they reproduce the bounding boxes, pivots and the convex / non-convex character that
matters for collision decomposition, not the detail.

Parts (bounding boxes in mm, in the link frame):

``ankle.stl`` (link ``ankle``; origin on the arch pivot, 22 mm below the foot mount)
    A 40 x 40 x 30.7 block, x, y in [-20, 20], z in [0, 30.7], with 3 mm chamfers on
    the two top edges parallel to x and a clevis slot 29.7 mm wide (y) x 7.5 mm high
    open at the front and back of its underside, where the two arch hubs sit.

``arch.stl`` (link ``front_arch``; origin on the arch pivot, hinge axis y)
    A curved bar 28.9 mm wide (y in [-14.45, 14.45]) and 7.5 mm thick whose centre
    line is a super-ellipse quadrant (|x/58|^3 + |(z+28)/28|^3 = 1) from the pivot
    (tangent +x) to the front roll pivot (58, 0, -28) (tangent -z), so the bar
    arches upward between its ends like a foot arch.  A hub disc r = 7 around the
    pivot (flattened at z = 4.7 for the ankle slot) and a boss disc r = 7.9 around
    the roll pivot (flattened at z = -34).
    Box x in [-7, 65.9], y in [-14.45, 14.45], z in [-34, 4.7] = 72.9 x 28.9 x 38.7.
    Non-convex.  The back arch uses this mesh rotated by pi about z.

``roll_link.stl`` (links ``front_roll`` / ``back_roll``; origin on the roll hinge,
hinge axis x)
    A crossbar with the hinge boss on top: the convex hull, in the y-z plane, of a
    disc r = 7 around the hinge axis (flattened at z = 2.3) and a bar
    y in [-25.5, 25.5], z in [-23, -8] (rounded lower corners r = 4), extruded over
    x in [-6.7, 8.6]: 15.3 x 51 x 25.3, z in [-23, 2.3].  The disc itself falls inside
    the hull, so the boss shows as the 13.2 mm flat apex over the hinge and the profile
    is a rounded trapezoid.  Convex; it encloses the three chain pins at
    (-2.1, {0, +-19.15}, -11.85).

``inner_link.stl`` (chain links 1, 3, 5, 7, 9; origin on the link's own pin, pin axis
x, next pin at (0, 0, 12.7))
    A stadium plate (semicircles r = 5.9 around both pins) in the y-z plane extruded
    over x in [-5.65, 5.65]: 11.3 x 11.8 x 24.5, y in [-5.9, 5.9], z in [-5.9, 18.6].
    Convex.

``outer_link.stl`` (chain links 2, 4, 6, 8; same frame; +y points DOWN to the ground)
    Two side plates 2.8 mm thick at x in +-[5.7, 8.5] (11.4 mm gap for the 11.3 mm
    inner links) with the stadium profile, joined by a rubber pad filling
    y in [5.9, 15.1] over the full x width and z in [-4, 16.7] (2 mm rounded lower
    corners); the plates run down into the pad.  17 x 21 x 24.5: x in [-8.5, 8.5],
    y in [-5.9, 15.1], z in [-5.9, 18.6].  Non-convex (a U in the x-y section); the
    pad face y = 15.1 is the lowest part of the sole.

Simplifications: pins, bores, screws, fillets and the elastic band are omitted; the
front and back arch hubs (same mesh) overlap around the arch pivot instead of being
interleaved; the roll link has no clevis slots for the chain links; the ankle slot
gives clearance for the hubs only, not for the full +-30 deg arch swing.  The meshes
are solid, so their volume centroids are not the published centres of mass (the real
parts are hollow / multi-material); the printed table reports both.

Construction: every part is a prism or a stepped prism (planar polygon profiles
extruded along one axis).  Cap polygons are triangulated by a deterministic ear
clipper, side walls are quads, and vertices are shared by exact coordinates, so each
mesh is closed, watertight and consistently wound by construction; no boolean engine
and no shapely are needed.  All profile points are rounded to 1e-4 mm before use and
the STL writer is a fixed-format numpy writer, so the output is byte-identical from
run to run.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import trimesh

QUANT_MM = 1e-4  # profile points are rounded to this grid (mm)

# ----------------------------------------------------------------------------------
# 2D helpers (all in mm)
# ----------------------------------------------------------------------------------


def q(v: float) -> float:
    """Round to the quantisation grid (and normalise -0.0)."""
    r = round(v / QUANT_MM) * QUANT_MM
    r = float(f"{r:.4f}")
    return 0.0 if r == 0.0 else r


def qpt(p) -> tuple[float, float]:
    return (q(p[0]), q(p[1]))


def dedup(pts):
    """Drop consecutive duplicates (and a closing duplicate)."""
    out = []
    for p in pts:
        p = qpt(p)
        if not out or p != out[-1]:
            out.append(p)
    if len(out) > 1 and out[0] == out[-1]:
        out.pop()
    return out


def signed_area(poly) -> float:
    a = 0.0
    n = len(poly)
    for i in range(n):
        x0, y0 = poly[i]
        x1, y1 = poly[(i + 1) % n]
        a += x0 * y1 - x1 * y0
    return 0.5 * a


def ccw(poly):
    return list(poly) if signed_area(poly) > 0 else list(reversed(poly))


def _seg_intersect(p1, p2, p3, p4) -> bool:
    def orient(a, b, c):
        v = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        return 0 if abs(v) < 1e-12 else (1 if v > 0 else -1)

    def on_seg(a, b, c):
        return (
            min(a[0], b[0]) - 1e-12 <= c[0] <= max(a[0], b[0]) + 1e-12
            and min(a[1], b[1]) - 1e-12 <= c[1] <= max(a[1], b[1]) + 1e-12
        )

    o1, o2 = orient(p1, p2, p3), orient(p1, p2, p4)
    o3, o4 = orient(p3, p4, p1), orient(p3, p4, p2)
    if o1 != o2 and o3 != o4:
        return True
    if o1 == 0 and on_seg(p1, p2, p3):
        return True
    if o2 == 0 and on_seg(p1, p2, p4):
        return True
    if o3 == 0 and on_seg(p3, p4, p1):
        return True
    if o4 == 0 and on_seg(p3, p4, p2):
        return True
    return False


def assert_simple(poly, name: str) -> None:
    """Raise if the closed polygon self-intersects (O(n^2), fine for n < 500)."""
    n = len(poly)
    assert len(set(poly)) == n, f"{name}: repeated vertex"
    for i in range(n):
        a, b = poly[i], poly[(i + 1) % n]
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue
            c, d = poly[j], poly[(j + 1) % n]
            if _seg_intersect(a, b, c, d):
                raise ValueError(f"{name}: edges {i} and {j} intersect")


def triangulate(poly):
    """Ear-clip a simple CCW polygon; returns index triples (CCW).

    At each step the ear with the largest minimum angle is clipped (first index wins
    ties), which is deterministic and avoids the worst slivers.
    """
    P = np.asarray(poly, dtype=float)
    idx = list(range(len(poly)))
    tris = []

    def min_angle(a, b, c):
        def ang(u, v):
            cu = math.hypot(*u) * math.hypot(*v)
            return math.acos(max(-1.0, min(1.0, (u[0] * v[0] + u[1] * v[1]) / cu)))

        return min(ang(b - a, c - a), ang(a - b, c - b), ang(a - c, b - c))

    while len(idx) > 3:
        m = len(idx)
        pts = P[idx]
        best, best_q = None, -1.0
        for k in range(m):
            a, b, c = pts[k - 1], pts[k], pts[(k + 1) % m]
            cr = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])
            if cr <= 1e-12:
                continue
            mask = np.ones(m, dtype=bool)
            mask[[k - 1, k, (k + 1) % m]] = False
            o = pts[mask]
            # points inside or on the candidate triangle block it (conservative)
            d1 = (b[0] - a[0]) * (o[:, 1] - a[1]) - (b[1] - a[1]) * (o[:, 0] - a[0])
            d2 = (c[0] - b[0]) * (o[:, 1] - b[1]) - (c[1] - b[1]) * (o[:, 0] - b[0])
            d3 = (a[0] - c[0]) * (o[:, 1] - c[1]) - (a[1] - c[1]) * (o[:, 0] - c[0])
            if np.any((d1 >= -1e-12) & (d2 >= -1e-12) & (d3 >= -1e-12)):
                continue
            qk = min_angle(a, b, c)
            if qk > best_q + 1e-12:
                best, best_q = k, qk
        if best is None:
            raise RuntimeError("ear clipping failed (polygon not simple?)")
        m = len(idx)
        tris.append((idx[best - 1], idx[best], idx[(best + 1) % m]))
        idx.pop(best)
    tris.append(tuple(idx))
    return tris


def arc(center, r, a0, a1, n):
    """Points on a circle from angle a0 to a1 (radians), n segments, n + 1 points."""
    cx, cy = center
    return [
        (cx + r * math.cos(a0 + (a1 - a0) * i / n), cy + r * math.sin(a0 + (a1 - a0) * i / n)) for i in range(n + 1)
    ]


def clip_halfplane(poly, axis: int, bound: float, keep_below: bool):
    """Sutherland-Hodgman clip of a polygon against x[axis] <= bound (or >=)."""

    def inside(p):
        return p[axis] <= bound if keep_below else p[axis] >= bound

    out = []
    n = len(poly)
    for i in range(n):
        cur, nxt = poly[i], poly[(i + 1) % n]
        if inside(cur):
            out.append(cur)
        if inside(cur) != inside(nxt):
            t = (bound - cur[axis]) / (nxt[axis] - cur[axis])
            p = [cur[0] + t * (nxt[0] - cur[0]), cur[1] + t * (nxt[1] - cur[1])]
            p[axis] = bound
            out.append(tuple(p))
    return out


def stadium(r, z0, z1, n_half):
    """Stadium in the (y, z) plane: semicircles of radius r around (0, z0), (0, z1)."""
    pts = arc((0.0, z1), r, 0.0, math.pi, n_half)  # top end, +y -> -y
    pts += arc((0.0, z0), r, math.pi, 2.0 * math.pi, n_half)  # bottom end, -y -> +y
    return pts


# ----------------------------------------------------------------------------------
# 3D assembly
# ----------------------------------------------------------------------------------


class MeshBuilder:
    """Collects triangles; vertices are shared by exact (quantised) coordinates."""

    def __init__(self, axis: int):
        # axis: extrusion axis; profiles are given in the (u, v) coordinates of the
        # cyclic successor axes, so a CCW profile has normal +axis.
        self.axis = axis
        self.u_ax = (axis + 1) % 3
        self.v_ax = (axis + 2) % 3
        self.index: dict[tuple[float, float, float], int] = {}
        self.verts: list[tuple[float, float, float]] = []
        self.faces: list[tuple[int, int, int]] = []

    def vid(self, uv, w) -> int:
        p = [0.0, 0.0, 0.0]
        p[self.u_ax], p[self.v_ax], p[self.axis] = uv[0], uv[1], w
        key = (p[0], p[1], p[2])
        if key not in self.index:
            self.index[key] = len(self.verts)
            self.verts.append(key)
        return self.index[key]

    def cap(self, poly, w, outward_positive: bool):
        """Planar cap at axis coordinate w; poly CCW in (u, v)."""
        for a, b, c in triangulate(poly):
            ia, ib, ic = (self.vid(poly[i], w) for i in (a, b, c))
            self.faces.append((ia, ib, ic) if outward_positive else (ia, ic, ib))

    def wall(self, p, qq, w0, w1):
        """Side quad over edge p -> q of a CCW profile, from w0 < w1 (outward)."""
        a, b = self.vid(p, w0), self.vid(qq, w0)
        c, d = self.vid(qq, w1), self.vid(p, w1)
        self.faces.append((a, b, c))
        self.faces.append((a, c, d))

    def mesh(self, name: str) -> trimesh.Trimesh:
        v = np.array(self.verts, dtype=np.float64) * 1e-3  # mm -> m
        f = np.array(self.faces, dtype=np.int64)
        m = trimesh.Trimesh(vertices=v, faces=f, process=False, validate=False)
        if m.volume < 0:
            raise RuntimeError(f"{name}: inverted mesh")
        return m


def prism(profile, axis: int, w0: float, w1: float, name: str) -> trimesh.Trimesh:
    """Extrude a simple polygon (in the cyclic (u, v) plane of `axis`) over [w0, w1]."""
    poly = ccw(dedup(profile))
    assert_simple(poly, name)
    b = MeshBuilder(axis)
    b.cap(poly, w1, True)
    b.cap(poly, w0, False)
    n = len(poly)
    for i in range(n):
        b.wall(poly[i], poly[(i + 1) % n], w0, w1)
    return b.mesh(name)


# ----------------------------------------------------------------------------------
# Parts (dimensions in mm)
# ----------------------------------------------------------------------------------


def make_ankle() -> trimesh.Trimesh:
    half, height, chamf = 20.0, 30.7, 3.0
    slot_half, slot_h = 14.85, 7.5
    # profile in (y, z), extruded along x
    prof = [
        (-half, 0.0),
        (-slot_half, 0.0),
        (-slot_half, slot_h),
        (slot_half, slot_h),
        (slot_half, 0.0),
        (half, 0.0),
        (half, height - chamf),
        (half - chamf, height),
        (-half + chamf, height),
        (-half, height - chamf),
    ]
    return prism(prof, axis=0, w0=-half, w1=half, name="ankle")


# arch parameters (mm)
ARCH_PIVOT = (0.0, 0.0)  # (x, z)
ROLL_PIVOT = (58.0, -28.0)
ARCH_THICK = 7.5
ARCH_HALF_WIDTH = 14.45
ARCH_HUB_R, ARCH_HUB_ZMAX = 7.0, 4.7
ARCH_BOSS_R, ARCH_BOSS_ZMIN = 7.9, -34.0
ARCH_SUPER_N = 3.0  # super-ellipse exponent of the centre line (2 = ellipse)
ARCH_N_CURVE = 96


def _arch_centerline(n: int):
    """Super-ellipse quadrant from the pivot (tangent +x) to the roll pivot (tangent -z).

    x = a * sin(t)^(2/N), z = zc + b * cos(t)^(2/N), t in [0, pi/2], with the centre
    (0, -28), a = 58, b = 28.  Returns points and unit normals pointing away from the
    centre (the "outer", upper side of the arch).
    """
    a = ROLL_PIVOT[0] - ARCH_PIVOT[0]
    b = ARCH_PIVOT[1] - ROLL_PIVOT[1]
    zc = ROLL_PIVOT[1]
    e = 2.0 / ARCH_SUPER_N
    pts, nrm = [], []
    for i in range(n + 1):
        t = 0.5 * math.pi * i / n
        s, c = math.sin(t), math.cos(t)
        x = a * s**e
        z = zc + b * c**e
        # outward normal of |x/a|^N + |z/b|^N = 1 is the gradient
        gx = (x / a) ** (ARCH_SUPER_N - 1) / a if x > 0 else 0.0
        gz = ((z - zc) / b) ** (ARCH_SUPER_N - 1) / b if z - zc > 0 else 0.0
        g = math.hypot(gx, gz)
        pts.append((x, z))
        nrm.append((gx / g, gz / g))
    return pts, nrm


def _outside_run(curve, centers_radii):
    """Longest contiguous run of curve points outside all given discs."""
    ok = [all(math.hypot(p[0] - c[0], p[1] - c[1]) > r + 1e-6 for c, r in centers_radii) for p in curve]
    runs, cur = [], []
    for p, flag in zip(curve, ok):
        if flag:
            cur.append(p)
        elif cur:
            runs.append(cur)
            cur = []
    if cur:
        runs.append(cur)
    if len(runs) != 1:
        raise RuntimeError("arch offset curve leaves the end discs more than once")
    return runs[0]


def _sweep_arc(center, r, p_from, p_to, avoid_dir, step_deg=7.5):
    """Arc on the disc from p_from to p_to that does NOT pass through avoid_dir."""
    a0 = math.atan2(p_from[1] - center[1], p_from[0] - center[0])
    a1 = math.atan2(p_to[1] - center[1], p_to[0] - center[0])
    ad = math.atan2(avoid_dir[1], avoid_dir[0])

    def norm(a):
        return a % (2.0 * math.pi)

    # counter-clockwise sweep from a0 to a1
    ccw_span = norm(a1 - a0)
    passes = norm(ad - a0) < ccw_span
    if passes:
        span = ccw_span - 2.0 * math.pi  # go clockwise instead
    else:
        span = ccw_span
    # break the sweep at the axis-aligned extremes so they are exact vertices
    # (they define the bounding box)
    a_end = a0 + span
    quarter = 0.5 * math.pi
    if span > 0:
        ks = range(math.floor(a0 / quarter) + 1, math.ceil(a_end / quarter))
    else:
        ks = range(math.ceil(a0 / quarter) - 1, math.floor(a_end / quarter), -1)
    cuts = [k * quarter for k in ks]
    bounds = [a0] + cuts + [a_end]
    pts = [(center[0] + r * math.cos(a0), center[1] + r * math.sin(a0))]
    for s0, s1 in zip(bounds[:-1], bounds[1:]):
        n = max(1, int(math.ceil(abs(math.degrees(s1 - s0)) / step_deg)))
        pts += arc(center, r, s0, s1, n)[1:]
    return pts[1:-1]  # the exit points themselves come from the offset curves


def arch_profile():
    """Closed (x, z) outline of the arch: offset band + hub disc + boss disc."""
    cl, nrm = _arch_centerline(ARCH_N_CURVE)
    h = 0.5 * ARCH_THICK
    outer = [(p[0] + h * n[0], p[1] + h * n[1]) for p, n in zip(cl, nrm)]
    inner = [(p[0] - h * n[0], p[1] - h * n[1]) for p, n in zip(cl, nrm)]
    discs = [(ARCH_PIVOT, ARCH_HUB_R), (ROLL_PIVOT, ARCH_BOSS_R)]
    outer = _outside_run(outer, discs)
    inner = _outside_run(inner, discs)
    # exact exit points on the circles (project the nearest samples radially is not
    # exact; instead intersect the offset polyline segment with the circle)

    def exit_point(run_end, beyond, center, r):
        # segment from a point outside (run_end) to the first point inside (beyond)
        lo, hi = 0.0, 1.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            p = (
                run_end[0] + mid * (beyond[0] - run_end[0]),
                run_end[1] + mid * (beyond[1] - run_end[1]),
            )
            if math.hypot(p[0] - center[0], p[1] - center[1]) > r:
                lo = mid
            else:
                hi = mid
        return (
            run_end[0] + lo * (beyond[0] - run_end[0]),
            run_end[1] + lo * (beyond[1] - run_end[1]),
        )

    full_outer = [(p[0] + h * n[0], p[1] + h * n[1]) for p, n in zip(cl, nrm)]
    full_inner = [(p[0] - h * n[0], p[1] - h * n[1]) for p, n in zip(cl, nrm)]

    def exits(run, full):
        i0 = full.index(run[0])
        i1 = full.index(run[-1])
        e_hub = exit_point(run[0], full[i0 - 1], ARCH_PIVOT, ARCH_HUB_R)
        e_boss = exit_point(run[-1], full[i1 + 1], ROLL_PIVOT, ARCH_BOSS_R)
        return e_hub, e_boss

    o_hub, o_boss = exits(outer, full_outer)
    i_hub, i_boss = exits(inner, full_inner)

    def away(run, ends, min_gap=0.3):
        # drop samples that would make a sliver edge next to an exit point
        return [p for p in run if all(math.dist(p, e) > min_gap for e in ends)]

    outer = away(outer, (o_hub, o_boss))
    inner = away(inner, (i_hub, i_boss))

    # bar leaves the hub along +x and arrives at the boss from +z
    boss_arc = _sweep_arc(ROLL_PIVOT, ARCH_BOSS_R, o_boss, i_boss, avoid_dir=(0.0, 1.0))
    hub_arc = _sweep_arc(ARCH_PIVOT, ARCH_HUB_R, i_hub, o_hub, avoid_dir=(1.0, 0.0))
    poly = [o_hub] + outer + [o_boss] + boss_arc + [i_boss] + list(reversed(inner)) + [i_hub] + hub_arc
    poly = clip_halfplane(poly, axis=1, bound=ARCH_HUB_ZMAX, keep_below=True)
    poly = clip_halfplane(poly, axis=1, bound=ARCH_BOSS_ZMIN, keep_below=False)
    return poly


def make_arch() -> trimesh.Trimesh:
    # profile in (x, z); extrusion axis y has cyclic plane (z, x), so swap to (z, x)
    prof = [(z, x) for x, z in arch_profile()]
    return prism(prof, axis=1, w0=-ARCH_HALF_WIDTH, w1=ARCH_HALF_WIDTH, name="arch")


def convex_hull_2d(points):
    """Andrew's monotone chain; CCW hull without collinear points (deterministic)."""
    pts = sorted(set(qpt(p) for p in points))

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 1e-9:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 1e-9:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]


def make_roll_link() -> trimesh.Trimesh:
    """Convex hull (in y-z) of the hinge boss and the crossbar, extruded along x."""
    x0, x1 = -6.7, 8.6
    half_y, z_top, z_bot = 25.5, 2.3, -23.0
    boss_r, z_bar_top, r_c = 7.0, -8.0, 4.0
    # hinge boss: disc r = 7 around the origin, flattened at z = 2.3
    pts = clip_halfplane(arc((0.0, 0.0), boss_r, 0.0, 2.0 * math.pi, 48)[:-1], 1, z_top, True)
    # crossbar: y in [-25.5, 25.5], z in [-23, -8], rounded lower corners r = 4
    pts += [(-half_y, z_bar_top), (half_y, z_bar_top)]
    pts += arc((-half_y + r_c, z_bot + r_c), r_c, math.pi, 1.5 * math.pi, 6)
    pts += arc((half_y - r_c, z_bot + r_c), r_c, 1.5 * math.pi, 2.0 * math.pi, 6)
    return prism(convex_hull_2d(pts), axis=0, w0=x0, w1=x1, name="roll_link")


LINK_R, LINK_PITCH = 5.9, 12.7


def make_inner_link() -> trimesh.Trimesh:
    prof = stadium(LINK_R, 0.0, LINK_PITCH, 24)
    return prism(prof, axis=0, w0=-5.65, w1=5.65, name="inner_link")


def make_outer_link() -> trimesh.Trimesh:
    """Stepped prism along x: plates (profile A) at |x| in [5.7, 8.5], pad (B) between.

    Profile A (y, z) = stadium plate run down into the pad; B = pad rectangle
    y in [5.9, 15.1], z in [-4, 16.7] with rounded corners at y = 15.1.  A and B share
    the chain S (pad sides and bottom); A \\ B is the plate-only region.
    """
    r, p = LINK_R, LINK_PITCH
    x_in, x_out = 5.7, 8.5
    y_pad0, y_pad1, z_pad0, z_pad1, r_pad = 5.9, 15.1, -4.0, 16.7, 2.0
    # where the plate arcs meet the pad end faces z = z_pad1 and z = z_pad0
    a_top = math.asin((z_pad1 - p) / r)
    a_bot = math.asin(z_pad0 / r)

    J1 = (y_pad0, z_pad1)
    J2 = (y_pad0, z_pad0)
    # S: shared chain J1 -> pad outer side -> J2
    S = [J1]
    S += [(y, z_pad1) for y in (8.0, 10.5, 13.1) if y < y_pad1 - r_pad + 1e-9]
    S += arc((y_pad1 - r_pad, z_pad1 - r_pad), r_pad, 0.5 * math.pi, 0.0, 4)
    S += [(y_pad1, z) for z in (10.7, 6.35, 2.0)]
    S += arc((y_pad1 - r_pad, z_pad0 + r_pad), r_pad, 0.0, -0.5 * math.pi, 4)
    S += [(y, z_pad0) for y in (10.5, 8.0)]
    S += [J2]
    # T: plate-only chain J2 -> around both pins -> J1
    T = [J2]
    # bottom end via -z (split there so the extreme point is a vertex) to -y
    T += arc((0.0, 0.0), r, a_bot, -0.5 * math.pi, 6)
    T += arc((0.0, 0.0), r, -0.5 * math.pi, -math.pi, 12)
    # top end from -y via +z
    T += arc((0.0, p), r, math.pi, 0.5 * math.pi, 12)
    T += arc((0.0, p), r, 0.5 * math.pi, a_top, 6)
    T += [J1]

    S = dedup(S)
    T = dedup(T)
    A = ccw(dedup(S + T[1:-1]))
    B = ccw(dedup(S + [J2]))  # closing edge J2 -> J1 is y = y_pad0
    AmB = ccw(dedup(T))  # closing edge J1 -> J2
    for poly, nm in ((A, "outer_link A"), (B, "outer_link B"), (AmB, "outer_link A-B")):
        assert_simple(poly, nm)

    def edges(poly):
        n = len(poly)
        return [(poly[i], poly[(i + 1) % n]) for i in range(n)]

    eB = set(edges(B))
    eA = set(edges(A))
    b = MeshBuilder(axis=0)
    b.cap(A, x_out, True)
    b.cap(A, -x_out, False)
    b.cap(AmB, x_in, False)  # faces the gap (-x)
    b.cap(AmB, -x_in, True)  # faces the gap (+x)
    for e in edges(A):
        b.wall(e[0], e[1], -x_out, -x_in)
        b.wall(e[0], e[1], x_in, x_out)
        if e in eB:
            b.wall(e[0], e[1], -x_in, x_in)
    for e in edges(B):
        if e not in eA:
            b.wall(e[0], e[1], -x_in, x_in)
    return b.mesh("outer_link")


# ----------------------------------------------------------------------------------
# Targets, checks, output
# ----------------------------------------------------------------------------------

# target bounding boxes in metres: (min xyz, max xyz)
TARGET_BOUNDS = {
    "ankle": ((-0.020, -0.020, 0.0), (0.020, 0.020, 0.0307)),
    "arch": ((-0.007, -0.01445, -0.034), (0.0659, 0.01445, 0.0047)),
    "roll_link": ((-0.0067, -0.0255, -0.0230), (0.0086, 0.0255, 0.0023)),
    "inner_link": ((-0.00565, -0.0059, -0.0059), (0.00565, 0.0059, 0.0186)),
    "outer_link": ((-0.0085, -0.0059, -0.0059), (0.0085, 0.0151, 0.0186)),
}
# parts that must be clearly non-convex (volume / hull volume below this)
NONCONVEX_MAX_RATIO = {"arch": 0.9, "outer_link": 0.9}
# published centres of mass (m), for information only
PUBLISHED_COM = {
    "ankle": (0.0, 0.0, 0.0154),
    "arch": (0.0356, -0.0011, -0.0078),
    "roll_link": (0.0010, 0.0, -0.0112),
    "inner_link": (0.0, 0.0, 0.00635),
    "outer_link": (0.0, 0.0037, 0.00635),
}

BUILDERS = {
    "ankle": make_ankle,
    "arch": make_arch,
    "roll_link": make_roll_link,
    "inner_link": make_inner_link,
    "outer_link": make_outer_link,
}


def build_all() -> dict[str, trimesh.Trimesh]:
    return {name: fn() for name, fn in BUILDERS.items()}


def stl_bytes(mesh: trimesh.Trimesh, name: str) -> bytes:
    """Binary STL with a fixed header and normals computed element-wise in float64."""
    tri = np.asarray(mesh.vertices, dtype=np.float64)[np.asarray(mesh.faces)]
    e1 = tri[:, 1] - tri[:, 0]
    e2 = tri[:, 2] - tri[:, 0]
    n = np.empty_like(e1)
    n[:, 0] = e1[:, 1] * e2[:, 2] - e1[:, 2] * e2[:, 1]
    n[:, 1] = e1[:, 2] * e2[:, 0] - e1[:, 0] * e2[:, 2]
    n[:, 2] = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    ln = np.sqrt(n[:, 0] * n[:, 0] + n[:, 1] * n[:, 1] + n[:, 2] * n[:, 2])
    n = n / ln[:, None]
    dt = np.dtype([("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attr", "<u2")])
    packed = np.zeros(len(tri), dtype=dt)
    packed["normal"] = n
    packed["vertices"] = tri
    header = f"footforge SoftFoot-Q {name} (metres, link frame)".encode("ascii")
    header = header.ljust(80, b" ")[:80]
    return header + np.uint32(len(tri)).astype("<u4").tobytes() + packed.tobytes()


def check(name: str, mesh: trimesh.Trimesh) -> dict:
    lo, hi = mesh.bounds
    tlo, thi = (np.asarray(t) for t in TARGET_BOUNDS[name])
    bbox_err = float(max(np.abs(lo - tlo).max(), np.abs(hi - thi).max()))
    ratio = float(mesh.volume / mesh.convex_hull.volume)
    return {
        "name": name,
        "vertices": len(mesh.vertices),
        "faces": len(mesh.faces),
        "size_mm": (hi - lo) * 1e3,
        "lo_mm": lo * 1e3,
        "hi_mm": hi * 1e3,
        "bbox_err_mm": bbox_err * 1e3,
        "watertight": bool(mesh.is_watertight),
        "winding": bool(mesh.is_winding_consistent),
        "volume_cm3": float(mesh.volume) * 1e6,
        "hull_ratio": ratio,
        "com_mm": np.asarray(mesh.center_mass) * 1e3,
        "ok": bool(
            mesh.is_watertight
            and mesh.is_winding_consistent
            and mesh.volume > 0
            and bbox_err <= 0.5e-3
            and ratio < NONCONVEX_MAX_RATIO.get(name, 1.0 + 1e-9)
        ),
    }


def main(argv: list[str]) -> int:
    out_dir = Path(argv[1]) if len(argv) > 1 else Path(__file__).resolve().parent
    out_dir.mkdir(parents=True, exist_ok=True)
    meshes = build_all()
    rows = []
    for name, mesh in meshes.items():
        (out_dir / f"{name}.stl").write_bytes(stl_bytes(mesh, name))
        rows.append(check(name, mesh))

    def f3(v, nd=1):
        return "(" + ", ".join(f"{x:{5 + nd}.{nd}f}" for x in v) + ")"

    print(f"wrote {len(meshes)} meshes to {out_dir}")
    print(
        f"{'part':<11}{'verts':>6}{'faces':>6}  {'size x,y,z [mm]':<24}"
        f"{'min [mm]':<27}{'max [mm]':<27}{'bbErr':>6} {'wt':>3} {'wind':>4}"
        f" {'vol cm3':>7} {'vol/hull':>8}  {'centroid [mm]':<24}{'pub. COM [mm]':<24}ok"
    )
    for r in rows:
        print(
            f"{r['name']:<11}{r['vertices']:>6}{r['faces']:>6}  {f3(r['size_mm']):<24}"
            f"{f3(r['lo_mm'], 2):<27}{f3(r['hi_mm'], 2):<27}{r['bbox_err_mm']:>6.3f}"
            f" {'Y' if r['watertight'] else 'N':>3} {'Y' if r['winding'] else 'N':>4}"
            f" {r['volume_cm3']:>7.3f} {r['hull_ratio']:>8.3f}  {f3(r['com_mm']):<24}"
            f"{f3(np.asarray(PUBLISHED_COM[r['name']]) * 1e3):<24}"
            f"{'OK' if r['ok'] else 'FAIL'}"
        )
    return 0 if all(r["ok"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
