"""The fit's matches on a micro-surface too large for one closest-point tree in memory (a
height map's lattice: millions of micro-triangles, whose tree took 720 bytes a micro-vertex
while it was built): a tree over each group of triangles in turn, every sample's nearest
kept over the groups, then the matches made from those as
:func:`core.fit.system.sample_matches` makes them, in the samples' order
(:class:`GroupedMatches`).

A group's tree is asked only for the samples that can have a nearer triangle in it: the
runs of samples (:meth:`Samples.parts`) whose faces' box, grown by their bound, meets the
group's box, and of those the samples within their bound of it. With the reference's faces
in a spatial order a run is a compact region, so most runs skip most groups unmade.
"""
from __future__ import annotations

from typing import Iterator

import numpy as np

from ..spatial.barycentric import barycentrics
from ..spatial.closest import ClosestPointIndex
from ..spatial.point_triangle import pair_closest
from .samples import CHUNK, Samples

# Triangles in one tree at a time: about 600 MB while it is built, 250 MB while it is asked.
GROUP = 1 << 20


def spatial_order(points: np.ndarray) -> np.ndarray:
    """The order of ``points`` (n, 3) along a Morton curve (10 bits an axis)."""
    lo = points.min(0)
    q = ((points - lo) / max(float(np.ptp(points, 0).max()), 1e-300) * 1023).astype(np.int64)
    code = np.zeros(len(points), np.int64)
    for bit in range(10):
        for axis in range(3):
            code |= ((q[:, axis] >> bit) & 1) << (3 * bit + axis)
    return np.argsort(code, kind="stable")


def triangle_groups(centroids: np.ndarray, ptr: np.ndarray, size: int = GROUP) -> list:
    """Groups of about ``size`` triangles at most, whole faces each, over compact boxes: the
    faces (``centroids`` (nf, 3); ``ptr`` (nf + 1,) their triangle ranges, a
    micro-mesh topology's ``face_triangle_ptr``) cut across the longest side of their box,
    the triangles shared out between the two sides' shares of the groups to be, until each
    part holds ``size`` or fewer: as many groups as runs of ``size`` would make. (Runs of a
    Morton order gave boxes that spanned distant parts of an assembly.) Returns int32 index
    arrays (int64 past 2³¹ triangles)."""
    counts = np.diff(ptr)
    kind = np.int32 if ptr[-1] < 2 ** 31 else np.int64
    out, todo = [], [np.arange(len(counts))]
    while todo:
        faces = todo.pop()
        total = int(counts[faces].sum())
        parts = -(-total // size)               # as many groups as runs of ``size`` make
        if parts <= 1 or len(faces) == 1:
            if len(faces):
                out.append(np.concatenate([np.arange(ptr[f], ptr[f + 1], dtype=kind)
                                           for f in faces]))
            continue
        c = centroids[faces]
        axis = int(np.argmax(np.ptp(c, 0)))
        order = faces[np.argsort(c[:, axis], kind="stable")]
        cut = np.searchsorted(np.cumsum(counts[order]), total * (parts // 2) / parts)
        cut = min(max(int(cut), 1), len(order) - 1)
        todo += [order[cut:], order[:cut]]
    return out


class GroupedMatches:
    """The matches of ``samples`` on the triangles ``T`` (m, 3) over ``X`` (n, 3), searched
    group by group (``groups``: index arrays into T covering it; ``bound`` (s,): a distance
    within which every sample has a triangle). Iterating yields, per about ``chunk`` samples
    in order, (points (c, 3), normals (c, 3), weights (c,), matched micro-triangles (c,),
    their corners (c, 3), the closest points' barycentrics (c, 3)) as
    :func:`core.fit.system.sample_matches` does (a sample none is found for within its
    bound is left out); after it, :attr:`distance` (s,) float32 holds each sample's distance
    to its triangle. With one group: one pass, one tree."""

    def __init__(self, X: np.ndarray, T: np.ndarray, groups: list, samples: Samples,
                 bound: np.ndarray, chunk: int = CHUNK):
        self.X, self.T, self.groups, self.samples, self.chunk = X, T, groups, samples, chunk
        self.bound = bound
        self.distance = None
        self.triangle = None

    def __iter__(self) -> Iterator[tuple]:
        X, T = self.X, self.T
        if len(self.groups) == 1:
            index = ClosestPointIndex(X, T[self.groups[0]])
            self.distance = np.empty(len(self.samples), np.float32)
            self.triangle = np.full(len(self.samples), -1, self.groups[0].dtype)
            for part, pts, normals, weights in self.samples.chunks(self.chunk):
                cp, f, d = index.query(pts, max_distance=self._reach(part))
                ok = np.flatnonzero(f >= 0)
                self.distance[part] = np.minimum(d, self._reach(part))    # (inf: none)
                t = self.groups[0][f[ok]].astype(np.int64)
                self.triangle[part.start + ok] = t
                corners = np.ascontiguousarray(T[t], dtype=np.int64)
                yield (pts[ok], normals[ok], weights[ok], t, corners,
                       barycentrics(cp[ok], X[corners]))
            return
        tri = self.triangle = self._nearest()
        for part, pts, normals, weights in self.samples.chunks(self.chunk):
            t = tri[part]
            ok = np.flatnonzero(t >= 0)
            t = t[ok].astype(np.int64)
            corners = np.ascontiguousarray(T[t], dtype=np.int64)
            c = X[corners]
            cp = pair_closest(pts[ok], c[:, 0], c[:, 1], c[:, 2])
            yield pts[ok], normals[ok], weights[ok], t, corners, barycentrics(cp, c)

    def _reach(self, part: slice) -> np.ndarray:
        return np.asarray(self.bound[part], dtype=np.float64) * (1.0 + 1e-6) + 1e-12

    def _nearest(self) -> np.ndarray:
        """(s,) each sample's nearest triangle (-1: none within its bound), the groups' trees
        made one at a time; :attr:`distance` set."""
        X, T, samples = self.X, self.T, self.samples
        best = self._reach(slice(None)).astype(np.float32)     # (float32: a tie at most)
        tri = np.full(len(best), -1, np.int32 if len(T) < 2 ** 31 else np.int64)
        ref = samples.reference
        runs = list(samples.parts(self.chunk))
        boxes = [(c.min((0, 1)), c.max((0, 1))) for c in
                 (ref.vertices[ref.faces[f]] for _, _, f in runs)]
        # each run's points made once, in float32 (12 bytes a sample), to find the samples
        # near a group; those are asked for in float64, as made
        points = [None] * len(runs)
        for group in self.groups:
            corners = X[T[group]]
            lo, hi = corners.min((0, 1)), corners.max((0, 1))
            del corners
            index = None
            for k, ((part, lv, f), (rlo, rhi)) in enumerate(zip(runs, boxes)):
                reach = best[part].max()
                if (rlo > hi + reach).any() or (rhi < lo - reach).any():
                    continue
                if points[k] is None:
                    points[k] = samples.points(lv, f).astype(np.float32)
                # widened by float32's rounding at the box's scale
                r = best[part][:, None] + np.float32(
                    1e-6 * max(1.0, float(np.abs([lo, hi]).max()) + float(reach)))
                near = np.flatnonzero(((points[k] >= (lo - r).astype(np.float32))
                                       & (points[k] <= (hi + r).astype(np.float32))).all(1))
                if not len(near):
                    continue
                if index is None:
                    index = ClosestPointIndex(X, T[group])
                _, fi, d = index.query(samples.points_at(lv, f, near),
                                       max_distance=best[part][near])
                closer = d < best[part][near]
                at = part.start + near[closer]
                best[at], tri[at] = d[closer], group[fi[closer]]
            del index
        self.distance = best
        return tri
