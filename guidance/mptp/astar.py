"""A* search on an implicit graph (seed 002, Algorithms 1 and 2).

The successor function yields (child, step cost, heuristic of the child); the closed list is
keyed by ``key(node)`` so that the caller decides which states are "the same" (for the MPTP a
position/time/course lattice, Option 1 of Algorithm 2). Ties in F prefer the larger G (the
deeper state). Closed states are never reopened, so an inconsistent heuristic (SSPH) may cost
optimality, as the thesis notes; an admissible, consistent one returns an optimal path.
``weight`` w >= 1 orders the open list by G + w H (weighted A*): with an admissible, consistent
H the path costs at most w times the optimum, and plateaus of equal G + H are left early.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Callable, Hashable, Iterable
from dataclasses import dataclass, field
from typing import Generic, TypeVar

N = TypeVar("N")


@dataclass(frozen=True, slots=True)
class SearchResult(Generic[N]):
    """``path`` from start to goal (empty unless ``status == "ok"``), its cost, the number of
    expanded states (EXST) and ``status``: "ok", "exhausted" (open list empty) or "limit".
    ``partial``: when not "ok", the path to the expanded node (not the start, with successors)
    with the smallest heuristic among those accepted by ``partial_ok`` (the best progress
    towards the goal; empty if none)."""

    path: list[N]
    cost: float
    expanded: int
    status: str
    partial: list[N] = field(default_factory=list)


def astar(
    start: N,
    expand: Callable[[N], Iterable[tuple[N, float, float]]],
    is_goal: Callable[[N], bool],
    key: Callable[[N], Hashable],
    max_expansions: int,
    h_start: float = 0.0,
    partial_ok: Callable[[N], bool] | None = None,
    weight: float = 1.0,
) -> SearchResult[N]:
    tie = itertools.count()
    k0 = key(start)
    nodes: dict[Hashable, N] = {k0: start}
    parent: dict[Hashable, Hashable | None] = {k0: None}
    best_g, best_h = {k0: 0.0}, {k0: h_start}
    open_list = [(weight * h_start, -0.0, next(tie), k0)]
    closed: set[Hashable] = set()
    expanded = 0
    progress: tuple[float, Hashable] | None = None  # (h, key) of the best partial end so far

    def path_to(k):
        path = []
        while k is not None:
            path.append(nodes[k])
            k = parent[k]
        return path[::-1]

    def failed(status: str) -> SearchResult[N]:
        return SearchResult([], float("inf"), expanded, status, path_to(progress[1]) if progress else [])

    while open_list:
        _, neg_g, _, k = heapq.heappop(open_list)
        g = -neg_g
        if k in closed or g > best_g[k]:
            continue
        node = nodes[k]
        if is_goal(node):
            return SearchResult(path_to(k), g, expanded, "ok")
        if expanded >= max_expansions:
            return failed("limit")
        closed.add(k)
        expanded += 1
        children = list(expand(node))
        if (
            k != k0
            and children
            and partial_ok is not None
            and (progress is None or best_h[k] < progress[0])
            and partial_ok(node)
        ):
            progress = (best_h[k], k)  # not the start, not a dead end
        for child, cost, h in children:
            kc = key(child)
            g2 = g + cost
            if kc in closed or g2 >= best_g.get(kc, float("inf")):
                continue
            best_g[kc], best_h[kc], nodes[kc], parent[kc] = g2, h, child, k
            heapq.heappush(open_list, (g2 + weight * h, -g2, next(tie), kc))
    return failed("exhausted")
