"""The spanning tree of a system's joints: the one walk of the joint graph that every part of
the suite uses (the scenario's tree and loop joints, its placement by joint coordinates, the
reduced-coordinate builders' plan, the reduced-coordinate reference).

The rule: breadth first from the ground, the joints to the ground first in file order (a
second one to a body already reached closes a loop through the ground), then from each body
not yet reached, in the bodies' order (the root of a floating part); a joint whose two sides
are already reached closes a loop. The walk reads only ``name`` of the bodies and ``body_a``,
``body_b`` (a body's name, or None for the ground) of the joints; a joint is known by its
index in the list, so that joints need no names.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass


@dataclass(frozen=True)
class SpanningTree:
    """A system's joints as a spanning tree and its loop closures (module docstring).

    ``tree``: the indices of the tree joints in the order reached; ``loops``: the indices of
    the joints that close a loop, in the order found; ``order``: the bodies' names in the order
    reached (every parent before its children); ``parent``: body -> (its parent body, None
    for the ground or for a floating root; the index of the joint that attaches it, None for a
    floating root); ``children``: body -> its children in the order reached, and None -> the
    roots (the bodies on the ground, then the floating roots)."""

    tree: tuple[int, ...]
    loops: tuple[int, ...]
    order: tuple[str, ...]
    parent: dict
    children: dict

    @property
    def floating_roots(self) -> tuple[str, ...]:
        """The roots of the parts joined to nothing, in the bodies' order."""
        return tuple(b for b in self.children[None] if self.parent[b][1] is None)


def spanning_tree(bodies, joints) -> SpanningTree:
    """The spanning tree of ``joints`` over ``bodies`` (module docstring). Every ``body_a`` and
    every ``body_b`` other than None must name one of ``bodies``."""
    joints = list(joints)
    names = [b.name for b in bodies]
    reached: set[str] = set()
    tree: list[int] = []
    loops: list[int] = []
    order: list[str] = []
    parent: dict = {}
    children: dict = {None: [], **{n: [] for n in names}}
    adj: dict[str, list[int]] = {n: [] for n in names}
    for k, j in enumerate(joints):
        if j.body_b is not None:
            adj[j.body_a].append(k)
            adj[j.body_b].append(k)

    def reach(body: str, up: str | None, k: int | None) -> None:
        reached.add(body)
        order.append(body)
        parent[body] = (up, k)
        children[up].append(body)
        queue.append(body)

    used: set[int] = set()
    queue: deque[str] = deque()
    for k, j in enumerate(joints):
        if j.body_b is not None:
            continue
        used.add(k)
        if j.body_a in reached:
            loops.append(k)
        else:
            tree.append(k)
            reach(j.body_a, None, k)
    while True:
        while queue:
            p = queue.popleft()
            for k in adj[p]:
                if k in used:
                    continue
                used.add(k)
                j = joints[k]
                other = j.body_b if j.body_a == p else j.body_a
                if other in reached:
                    loops.append(k)
                else:
                    tree.append(k)
                    reach(other, p, k)
        rest = [n for n in names if n not in reached]
        if not rest:
            break
        reach(rest[0], None, None)
    return SpanningTree(
        tuple(tree),
        tuple(loops),
        tuple(order),
        parent,
        {p: tuple(c) for p, c in children.items()},
    )


__all__ = ["SpanningTree", "spanning_tree"]
