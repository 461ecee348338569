"""Trajectory restrictions of the rules (spec §7.7, 6.215-6.219): per-node masks of the
navigation reach set that a rule disables.

Frames: the tree's samples are LCF of a grid placed at ``pose`` (X+ heading, Y+ left, Z+ up)
[m]; points given to these functions are GCF (ENU) [m]. A node is disabled when any sample of
any movement from the root to it violates the restriction, so a disabled node disables its
subtree (``ReachSetTree.along_paths`` with ``np.logical_or``).
"""

from __future__ import annotations

import numpy as np
import shapely

from avoidance.reachset.frames import GridPose
from avoidance.reachset.tree import ReachSetTree


def right_plane_heading_mask(
    tree: ReachSetTree, pose: GridPose, collision_point: np.ndarray, tol: float = 1e-6, horizon: float = 0.0
) -> np.ndarray:
    """(6.215-6.216) Separation plane through the UAS (grid origin), the collision point and
    the vertical; nodes with any sample more than ``tol`` [m] left of it (left of the line
    origin -> collision point) are disabled. (6.217) With ``horizon`` [s] > 0, also nodes whose
    linear projection ``tip + v·t``, t in [0, horizon], from the movement's end (a decision
    point: the trajectory can be re-planned there) with its end velocity ``v`` (last sample
    step) gets more than ``tol`` left: a trajectory ending on the right but heading left.
    Only applies while the collision point is in front (X+ > 0); else nothing is disabled. (A
    turn at a bounded rate starts along the heading: with ``tol`` = 0 a heading a fraction of a
    degree left of the line disables every trajectory.)"""
    cp = pose.to_lcf(np.asarray(collision_point, float))
    if cp[0] <= 0.0:
        return np.zeros(tree.n_nodes, bool)
    u = cp[:2] / max(float(np.hypot(cp[0], cp[1])), 1e-9)
    s = tree.samples
    left = u[0] * s[..., 1] - u[1] * s[..., 0]  # z of u x p: > 0 = left
    bad = (left > tol).any(axis=1)
    if horizon > 0.0:  # left() is linear: the projection stays right iff its end at the horizon does
        n_sub = s.shape[1] - 1
        v = (s[:, -1] - s[:, -2]) * n_sub / tree.period
        end = s[:, -1] + horizon * v
        bad |= u[0] * end[:, 1] - u[1] * end[:, 0] > tol
    return tree.along_paths(bad, np.logical_or)


def safety_margin_mask(
    tree: ReachSetTree,
    pose: GridPose,
    collision_point: np.ndarray,
    margin: float,
    barrel_half_height: float | None = None,
    tol: float = 0.0,
) -> np.ndarray:
    """(6.218) ball: disable nodes with a sample closer than ``margin`` [m] to the collision
    point; (6.219, A-20) well-clear barrel when ``barrel_half_height`` [m] is given: closer than
    ``margin`` horizontally **and** within the height band. When the grid origin itself is
    already inside the volume, the radius used is the origin's own distance (the breach is
    reported by the caller); the first movement may come ``tol`` [m] closer (:func:`_radius`)."""
    cp = pose.to_lcf(np.asarray(collision_point, float))
    d = tree.samples - cp
    if barrel_half_height is None:
        dist = np.linalg.norm(d, axis=-1)
        here = float(np.linalg.norm(cp))
        inside_band = np.ones(dist.shape, bool)
    else:
        dist = np.hypot(d[..., 0], d[..., 1])
        here = float(np.hypot(cp[0], cp[1]))
        inside_band = np.abs(d[..., 2]) < barrel_half_height
    return tree.along_paths(((dist < _radius(tree, margin, here, tol) - 1e-9) & inside_band).any(axis=1), np.logical_or)


def moving_margin_mask(
    tree: ReachSetTree, pose: GridPose, peer_pos: np.ndarray, peer_vel: np.ndarray, margin: float, tol: float = 0.0
) -> np.ndarray:
    """Safety margin around a peer flying on at constant velocity: disable nodes with a sample
    closer than ``margin`` [m] to where the peer is at that sample's time. ``peer_pos`` GCF [m]
    at the grid's time, ``peer_vel`` GCF [m/s]. Radius as for the ball (:func:`_radius`)."""
    p0 = pose.to_lcf(np.asarray(peer_pos, float))
    v = pose.vec_to_lcf(np.asarray(peer_vel, float))
    peer = p0 + tree.sample_times()[..., None] * v
    dist = np.linalg.norm(tree.samples - peer, axis=-1)
    return tree.along_paths(
        (dist < _radius(tree, margin, float(np.linalg.norm(p0)), tol) - 1e-9).any(axis=1), np.logical_or
    )


def _radius(tree: ReachSetTree, margin: float, here: float, tol: float) -> np.ndarray:
    """(N, 1) radius a node's samples must keep [m]: ``margin``, or the current distance
    ``here`` when already closer; the first movement may come ``tol`` closer than that (a turn
    at a bounded rate starts along the heading), later ones not (no creeping in frame by frame)."""
    keep = min(margin, here)
    return np.where(tree.depth <= 1, keep - tol, keep)[:, None]


def path_clearance(tree: ReachSetTree, pose: GridPose, points: np.ndarray) -> np.ndarray:
    """(N,) smallest distance [m] of any sample on the path root -> node to any of ``points``
    (K, 3) GCF."""
    p = pose.to_lcf(np.asarray(points, float).reshape(-1, 3))
    own = np.linalg.norm(tree.samples[:, :, None, :] - p[None, None], axis=-1).min(axis=(1, 2))
    return tree.along_paths(own, np.minimum)


def widest_per_cell(tree: ReachSetTree, feasible: np.ndarray, clearance: np.ndarray) -> np.ndarray:
    """Nodes to disable so that of the feasible nodes ending in one cell only the one with the
    largest ``clearance`` stays (ties: cheaper, then shallower): whichever cell the path search
    picks, it gets the trajectory keeping farthest from the collision points, which turns away
    first instead of postponing the turn to a later frame."""
    out = np.zeros(tree.n_nodes, bool)
    nodes = np.flatnonzero(feasible & (tree.tip_cell >= 0))
    if len(nodes) == 0:
        return out
    order = np.lexsort((tree.depth[nodes], tree.cost[nodes], -clearance[nodes], tree.tip_cell[nodes]))
    ranked = nodes[order]
    first = np.r_[True, tree.tip_cell[ranked][1:] != tree.tip_cell[ranked][:-1]]
    out[ranked[~first]] = True
    return out


def weather_masks(tree: ReachSetTree, pose: GridPose, body, velocity: np.ndarray, dt: float, margin: float):
    """(hard, soft) node masks of a weather cell (spec §7.5): a node is hard when a sample of its
    path lies in the body, soft when one lies within ``margin`` [m] of it. ``body`` is the cell's
    polygon GCF (x east, y north) [m] at ``dt`` [s] before the grid's time, moving with
    ``velocity`` GCF [m/s]: each sample is tested against the body where it is at that sample's
    time (the sample shifted back by the cell's motion)."""
    xy = pose.to_gcf(tree.samples)[..., :2] - (dt + tree.sample_times())[..., None] * np.asarray(velocity, float)
    x, y = xy[..., 0].ravel(), xy[..., 1].ravel()
    shape = tree.samples.shape[:2]
    inside = shapely.contains_xy(body, x, y).reshape(shape).any(axis=1)
    near = shapely.dwithin(body, shapely.points(x, y), margin).reshape(shape).any(axis=1)
    return tree.along_paths(inside, np.logical_or), tree.along_paths(near, np.logical_or)
