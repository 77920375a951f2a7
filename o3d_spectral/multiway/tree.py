"""Spanning trees of the pairs and the poses chained along them.

:func:`maximum_spanning_tree` is Kruskal's, with an optional test that each join must
pass: every cloud of one tree against every cloud of the other, as the join would place
them (the free-space test of :mod:`o3d_spectral.multiway.visibility`). :func:`chained`
places each cloud in the first one's frame along a tree.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

__all__ = ["maximum_spanning_tree", "chained", "Joinable"]

#: ``joinable(a, b, a_to_b)``: whether cloud ``a`` may lie where ``a_to_b`` (4, 4) puts it
#: in cloud ``b``'s frame.
Joinable = Callable[[int, int, NDArray[np.float64]], bool]


def maximum_spanning_tree(
    n: int, weighted: list[tuple[int, int, float]],
    transformations: dict[tuple[int, int], NDArray[np.float64]] | None = None,
    joinable: Joinable | None = None,
) -> list[tuple[int, int]]:
    """Kruskal's maximum spanning forest of ``n`` nodes over the edges ``(i, j, weight)``;
    ties broken by the nodes' indices. Returns the chosen ``(i, j)``.

    With ``joinable``, an edge that would join two trees is taken only when
    ``joinable(a, b, a_to_b)`` holds for every cloud ``a`` of one and ``b`` of the other,
    placed as the joined tree would place them (``transformations[(i, j)]`` maps cloud
    ``i`` onto cloud ``j``); else it is passed over, and a later edge may join them."""
    members = {k: [k] for k in range(n)}     # a tree's root -> its clouds
    root = list(range(n))
    pose = [np.eye(4) for _ in range(n)]      # each cloud's pose in its root's frame
    tree = []
    for i, j, _ in sorted(weighted, key=lambda e: (-e[2], e[0], e[1])):
        a, b = root[i], root[j]
        if a == b:
            continue
        move = None
        if joinable is not None:
            # Tree b moved into tree a's frame: cloud j where the edge puts it against i.
            move = pose[i] @ np.linalg.inv(transformations[(i, j)]) @ np.linalg.inv(pose[j])
            if not all(joinable(u, v, np.linalg.inv(move @ pose[v]) @ pose[u])
                       for u in members[a] for v in members[b]):
                continue
        for v in members[b]:
            root[v] = a
            if move is not None:
                pose[v] = move @ pose[v]
        members[a] += members.pop(b)
        tree.append((i, j))
    return tree


def chained(
    n: int, tree: list[tuple[int, int]], transformations: dict[tuple[int, int], NDArray]
) -> list[NDArray[np.float64] | None]:
    """Each cloud's pose in cloud 0's frame chained along ``tree`` from cloud 0 (None for
    the clouds it does not reach); ``transformations[(i, j)]`` maps cloud i onto cloud j."""
    poses: list[NDArray[np.float64] | None] = [None] * n
    poses[0] = np.eye(4)
    frontier = [0]
    while frontier:
        k = frontier.pop(0)
        for i, j in tree:
            if i == k and poses[j] is None:
                poses[j] = poses[i] @ np.linalg.inv(transformations[(i, j)])
                frontier.append(j)
            elif j == k and poses[i] is None:
                poses[i] = poses[j] @ transformations[(i, j)]
                frontier.append(i)
    return poses
