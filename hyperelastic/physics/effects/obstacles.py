"""Rigid obstacles (-obstacle KIND:VALUES), one class per kind, listed in KINDS.

A kind declares what contact (contact.py) and the pictures need of its shape at values v (the numbers -obstacle gives,
moved by the obstacle's translation): the distance of nodes to it and the distance's gradient, the time of impact of
a straight move, the time of impact of a straight move against the obstacle moving between two positions, and a
drawing (points and triangles). The barrier's tangent takes b'' g g^T only: every kind is convex with the body outside,
so the distance's Hessian is positive semi-definite and enters with the factor b' < 0, which IPC's positive
semi-definite projection drops (a plane's Hessian is 0; a sphere's (I - g g^T)/rho; a box's, opposite an edge or a
corner, likewise). A concave kind (a cavity) would need its Hessian in Contact.linearize.

Adding a kind = one class here (a subclass of ObstacleKind with its name, values, count and the methods above) and
its line in KINDS: the option's parser, -help, the error lines, the contact effect and the drawings follow
(tests/test_contact.py adds a throw-away kind that way). A triangulated obstacle (`mesh:FILE`) is not analytic: it joins
self-contact's collision mesh (self_contact.py)."""
import os
import re
from dataclasses import dataclass

import numpy as np

from ...core.errors import UserError
from ...mesh.read import read_meshio


class ObstacleKind:
    """One kind of rigid obstacle (the module's docstring). Values are a numpy array of the kind's numbers; the first
    three are a point of it that a translation moves (a plane overrides `moved`)."""
    name = ""
    values = ""                  # "NX,NY,NZ,D: what they mean", for -help and the error lines
    count = 0                    # how many numbers -obstacle gives
    analytic = True              # False: a triangulated surface, handled by self-contact (self_contact.py)

    @classmethod
    def parse(cls, body, text):
        """(values, surface) from the text after `KIND:` (surface: None, or a triangulated kind's (points,
        triangles)); one line where they are not the kind's."""
        try:
            vals = [float(s) for s in body.split(",")]
        except ValueError:
            vals = []
        if len(vals) != cls.count or not np.all(np.isfinite(vals)):
            raise UserError(f"option -obstacle: '{text}': {cls.name} takes {NUMBERS.get(cls.count, cls.count)} "
                            f"numbers, {cls.values}")
        return tuple(cls.check(vals, text)), None

    @classmethod
    def check(cls, vals, text):
        """The numbers, checked and normalised (one line where they describe no obstacle)."""
        return vals

    @staticmethod
    def moved(v, u):
        """The values v moved by the translation u."""
        v = v.copy()
        v[:3] += u
        return v

    @staticmethod
    def distances(v, x):
        """(d, g): the distance of the nodes x (n, 3) to the obstacle (negative inside) and its gradient (unit)."""
        raise NotImplementedError

    @staticmethod
    def time_of_impact(v, x, dx):
        """Per node, the fraction s >= 0 of the straight move dx at which it first touches the obstacle (inf if
        never)."""
        raise NotImplementedError

    @classmethod
    def impact_moving(cls, old, new, a, b):
        """Per node, the fraction s of the straight move a -> b at which it meets the obstacle moving (by a
        translation) from values `old` to `new`: relative to the obstacle, the node moves b - a - (its translation)."""
        return cls.time_of_impact(old, a, b - a - (new[:3] - old[:3]))

    @staticmethod
    def drawing(v, lo, hi):
        """(points (n, 3), triangles (m, 3)) of the obstacle at values v, as far as a picture of a body in the box
        [lo, hi] needs (a plane: a square about the box's centre, twice its diagonal wide)."""
        raise NotImplementedError

    @staticmethod
    def inner_points(v):
        """Points (k, 3) of the obstacle at values v that lie inside the body only where the whole obstacle does (no
        node of the body being inside it): its centre for a ball or a box; none for a half-space (the default)."""
        return np.zeros((0, 3))


NUMBERS = {4: "four", 6: "six"}


class Plane(ObstacleKind):
    name = "plane"
    values = "NX,NY,NZ,D: the half-space NX x + NY y + NZ z > D is free (the normal points into the body)"
    count = 4

    @classmethod
    def check(cls, vals, text):
        n = np.linalg.norm(vals[:3])
        if n == 0:
            raise UserError(f"option -obstacle: '{text}': the plane's normal is zero")
        return [v / n for v in vals]

    @staticmethod
    def moved(v, u):
        v = v.copy()
        v[3] += float(v[:3] @ u)
        return v

    @staticmethod
    def distances(v, x):
        return x @ v[:3] - v[3], np.broadcast_to(v[:3], x.shape)

    @staticmethod
    def time_of_impact(v, x, dx):
        rate = dx @ v[:3]
        d = x @ v[:3] - v[3]
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(rate < 0, d / -rate, np.inf)

    @classmethod
    def impact_moving(cls, old, new, a, b):
        # (the signed distance (a + s (b - a)) . n - D(s) is linear in s: its offset moves linearly too)
        d0, d1 = a @ old[:3] - old[3], b @ new[:3] - new[3]
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(d1 < d0, np.where(d0 <= 0, 0.0, d0 / (d0 - d1)), np.inf)

    @staticmethod
    def drawing(v, lo, hi):
        n = v[:3]
        c = 0.5 * (np.asarray(lo) + np.asarray(hi))
        c = c - (c @ n - v[3]) * n                          # (the box's centre projected onto the plane)
        size = max(float(np.linalg.norm(np.asarray(hi) - np.asarray(lo))), 1e-300)
        t1 = np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))])
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(n, t1)
        points = np.array([c + size * (a * t1 + b * t2) for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
        return points, np.array([[0, 1, 2], [0, 2, 3]])


class Sphere(ObstacleKind):
    name = "sphere"
    values = "CX,CY,CZ,R: a rigid ball of radius R (the body stays outside)"
    count = 4

    @staticmethod
    def inner_points(v):
        return np.asarray(v[:3], float)[None]

    @classmethod
    def check(cls, vals, text):
        if vals[3] <= 0:
            raise UserError(f"option -obstacle: '{text}': the sphere's radius must be > 0")
        return vals

    @staticmethod
    def distances(v, x):
        r = x - v[:3]
        rho = np.linalg.norm(r, axis=1)
        return rho - v[3], r / np.maximum(rho, 1e-300)[:, None]

    @staticmethod
    def time_of_impact(v, x, dx):
        r = x - v[:3]
        a, b, c = (dx * dx).sum(axis=1), 2 * (r * dx).sum(axis=1), (r * r).sum(axis=1) - v[3] ** 2
        disc = b * b - 4 * a * c
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a)
        return np.where((disc >= 0) & (b < 0) & (a > 0), np.maximum(s, 0.0), np.inf)

    @staticmethod
    def drawing(v, lo, hi, n=24):
        th = np.linspace(0, np.pi, n + 1)[1:-1]                    # (latitudes between the poles)
        ph = np.linspace(0, 2 * np.pi, 2 * n, endpoint=False)
        T, P = np.meshgrid(th, ph, indexing="ij")
        ring = np.c_[(np.sin(T) * np.cos(P)).ravel(), (np.sin(T) * np.sin(P)).ravel(), np.cos(T).ravel()]
        points = v[:3] + v[3] * np.vstack([[0, 0, 1.0], ring, [0, 0, -1.0]])
        m, k = len(th), len(ph)
        idx = 1 + np.arange(m * k).reshape(m, k)
        nxt = np.roll(idx, -1, axis=1)
        tris = [np.c_[np.zeros(k, int), idx[0], nxt[0]]]
        for i in range(m - 1):
            tris += [np.c_[idx[i], idx[i + 1], nxt[i]], np.c_[nxt[i], idx[i + 1], nxt[i + 1]]]
        tris.append(np.c_[np.full(k, len(points) - 1), nxt[-1], idx[-1]])
        return points, np.concatenate(tris)


class Box(ObstacleKind):
    name = "box"
    values = "X0,Y0,Z0,X1,Y1,Z1: a rigid axis-aligned box between those corners (the body stays outside)"
    count = 6

    @staticmethod
    def inner_points(v):
        return ((np.asarray(v[:3], float) + np.asarray(v[3:6], float)) / 2)[None]

    @classmethod
    def check(cls, vals, text):
        if not all(a < b for a, b in zip(vals[:3], vals[3:])):
            raise UserError(f"option -obstacle: '{text}': the box's first corner must be below its second in x, y "
                            "and z")
        return vals

    @staticmethod
    def moved(v, u):
        v = v.copy()
        v[:3] += u
        v[3:] += u
        return v

    @staticmethod
    def distances(v, x):
        # outside: |q|, q the excess over the half-widths per axis (Euclidean distance to the box; gradient q/|q|,
        # away from the nearest face, edge or corner); inside: the largest (negative) excess, the nearest face's normal
        c, e = 0.5 * (v[:3] + v[3:]), 0.5 * (v[3:] - v[:3])
        r = x - c
        over = np.abs(r) - e
        q = np.maximum(over, 0.0)
        out = np.linalg.norm(q, axis=1)
        inside = out <= 0
        d = np.where(inside, over.max(axis=1), out)
        g = np.sign(r) * q / np.maximum(out, 1e-300)[:, None]
        if inside.any():
            k = np.argmax(over[inside], axis=1)
            gi = np.zeros((int(inside.sum()), 3))
            gi[np.arange(len(k)), k] = np.sign(r[inside, k])
            g[inside] = gi
        return d, g

    @staticmethod
    def time_of_impact(v, x, dx):
        # the slabs: per axis the interval of s in which the coordinate lies between the faces; the ray enters the
        # box at the latest entry, if that is before the earliest exit
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = (v[:3] - x) / dx, (v[3:] - x) / dx
        still = dx == 0
        between = (x >= v[:3]) & (x <= v[3:])
        lo = np.where(still, np.where(between, -np.inf, np.inf), np.minimum(t0, t1))
        hi = np.where(still, np.where(between, np.inf, -np.inf), np.maximum(t0, t1))
        enter, leave = lo.max(axis=1), hi.min(axis=1)
        return np.where((enter <= leave) & (leave >= 0), np.maximum(enter, 0.0), np.inf)

    @staticmethod
    def drawing(v, lo, hi):
        corner = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], float)
        points = v[:3] + corner * (v[3:] - v[:3])
        quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
        return points, np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])


class TriangleMesh(ObstacleKind):
    name = "mesh"
    values = "FILE: a rigid triangulated surface (.stl, .obj, .msh, ... as meshio reads it; its triangles)"
    analytic = False

    @classmethod
    def parse(cls, body, text):
        return (body,), read_surface(body, text)


KINDS = {k.name: k for k in (Plane, Sphere, Box, TriangleMesh)}
INSIDE_SAMPLE = 64          # vertices of a triangulated obstacle tested for lying inside the body (Obstacle.inside_test)


def kinds_help():
    """`KIND:VALUES; ...` of every kind, for -help and the error lines."""
    return "; ".join(f"{k}:{c.values}" for k, c in KINDS.items())


@dataclass(frozen=True)
class Obstacle:
    kind: str                 # its kind's name in KINDS
    values: tuple             # the kind's numbers (a triangulated obstacle's: its file)
    motion: tuple = None      # three TimeFunctions of its translation, or None (fixed)
    text: str = ""
    surface: tuple = None     # a triangulated obstacle's (points (n, 3), triangles (m, 3)) as read

    @property
    def form(self):
        """Its kind (an ObstacleKind subclass)."""
        return KINDS[self.kind]

    def shift(self, t):
        """The obstacle's translation at time t."""
        return np.zeros(3) if self.motion is None else np.array([m(t) for m in self.motion])

    def at(self, t):
        """Its values at time t (moved by its translation)."""
        return self.form.moved(np.array(self.values, float), self.shift(t))

    def inside_test(self, t):
        """(points (k, 3), all): the obstacle is wholly inside the body where any (all=False) or all (all=True) of
        these lie inside it: a ball's or a box's centre (ObstacleKind.inner_points); a triangulated obstacle's
        vertices, at most INSIDE_SAMPLE of them evenly spaced (one crossing the body's surface is another error)."""
        if not self.form.analytic:
            P = self.surface[0]
            return P[np.linspace(0, len(P) - 1, min(len(P), INSIDE_SAMPLE)).astype(int)] + self.shift(t), True
        return self.form.inner_points(self.at(t)), False

    def drawing(self, t, lo, hi):
        """(points, triangles) of the obstacle at time t, for a picture of a body in the box [lo, hi]."""
        if not self.form.analytic:
            return self.surface[0] + self.shift(t), self.surface[1]
        return self.form.drawing(self.at(t), lo, hi)


def linear_motion(obstacles, t0, t1):
    """Whether every obstacle's translation is linear in t over [t0, t1] (at the midpoint, to 1e-9 of the move)."""
    tm = 0.5 * (t0 + t1)
    ok = True
    for o in obstacles:
        if o.motion is not None:
            a, b = o.shift(t0), o.shift(t1)
            ok = ok and np.allclose(o.shift(tm), 0.5 * (a + b), rtol=0, atol=1e-9 * (1 + np.abs(b - a).max()))
    return bool(ok)


def parse(text, motion):
    """The Obstacle of one -obstacle item `KIND:VALUES` moving by `motion`, or one line saying why not."""
    m = re.fullmatch(r"\s*(\w+)\s*:\s*(.*?)\s*", text)
    kind = m.group(1) if m else ""
    if kind not in KINDS:
        raise UserError(f"option -obstacle: '{text}' is not an obstacle (give {kinds_help()}, several separated by "
                        "';')")
    values, surface = KINDS[kind].parse(m.group(2), text)
    return Obstacle(kind, values, motion, text.strip(), surface)


def read_surface(path, text):
    """(points, triangles) of a triangulated obstacle's file (meshio), or one line saying why not."""
    if not os.path.isfile(path):
        raise UserError(f"option -obstacle: '{text}': cannot read {path}: no such file")
    mesh = read_meshio(path, f"option -obstacle: '{text}': {path}")
    tris = [c.data for c in mesh.cells if c.type == "triangle"]
    points = np.asarray(mesh.points, float)
    if not tris or points.ndim != 2 or points.shape[1] != 3 or not np.isfinite(points).all():
        raise UserError(f"option -obstacle: '{text}': {path} holds no triangles with finite 3-d points")
    tris = np.concatenate(tris).astype(np.int64)
    used = np.unique(tris)
    return points[used], np.searchsorted(used, tris)
