"""A small XML reader for model files: elements with their line numbers, and the one error
type of the model readers.

The tree is built with the standard library's expat parser (no engine's parser, no third-party
package), keeping each element's line so that every message names the file, the element, its
line and the rule. Files above :data:`MAX_BYTES` are refused before parsing; expat itself
refuses entity expansion beyond its amplification limit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

from scenarios.schema import InputError

#: a model file larger than this is refused unread (robot descriptions are tens to hundreds
#: of KiB; Talos' full URDF, one of the largest in example-robot-data, is ~150 KiB)
MAX_BYTES = 16 << 20


class ModelError(InputError):
    """A model file (URDF or MJCF) that cannot be read into a system of bodies. The message
    names the file, the element (with its line) and the rule; ``problems`` lists
    ``(element, rule)`` pairs, ``path`` the file."""

    def __init__(self, message: str, path: str | None = None, problems=()):
        super().__init__(message)
        self.path = path
        self.problems = list(problems)


@dataclass(eq=False)
class Node:
    """One XML element: ``tag``, ``attrib`` (name -> text), ``children`` in file order and the
    ``line`` it starts on."""

    tag: str
    attrib: dict
    line: int
    children: list = field(default_factory=list)
    parent: Node | None = field(default=None, repr=False)

    def find(self, tag: str) -> Node | None:
        for c in self.children:
            if c.tag == tag:
                return c
        return None

    def findall(self, tag: str) -> list[Node]:
        return [c for c in self.children if c.tag == tag]

    def get(self, name: str, default=None):
        return self.attrib.get(name, default)

    def label(self) -> str:
        """``<tag name='..'> (line N)``: how messages name the element."""
        name = self.attrib.get("name")
        inner = f"<{self.tag} name={name!r}>" if name is not None else f"<{self.tag}>"
        return f"{inner} (line {self.line})"


def parse(path: str | Path) -> Node:
    """The root element of the XML file ``path``; :class:`ModelError` naming the file, the
    line and expat's reason when it is missing, too large or not well-formed XML."""
    path = Path(path)
    if not path.is_file():
        raise ModelError(f"model file {path}: does not exist or is not a file", path=str(path))
    size = path.stat().st_size
    if size > MAX_BYTES:
        raise ModelError(
            f"model file {path}: {size} bytes, above the {MAX_BYTES >> 20} MiB a robot "
            "description needs: not read",
            path=str(path),
        )
    return parse_bytes(path.read_bytes(), str(path))


def parse_bytes(data: bytes, where: str) -> Node:
    """The root element of the XML document ``data`` (``where`` names it in messages)."""
    p = expat.ParserCreate()
    stack: list[Node] = []
    root: list[Node] = []

    def start(tag, attrs):
        n = Node(tag, dict(attrs), p.CurrentLineNumber)
        if stack:
            n.parent = stack[-1]
            stack[-1].children.append(n)
        else:
            root.append(n)
        stack.append(n)

    def end(_tag):
        stack.pop()

    p.StartElementHandler = start
    p.EndElementHandler = end
    try:
        p.Parse(data, True)
    except expat.ExpatError as exc:
        raise ModelError(
            f"model file {where}: not well-formed XML at line {exc.lineno}, column "
            f"{exc.offset}: {expat.errors.messages[exc.code]}",
            path=where,
        ) from None
    return root[0]
