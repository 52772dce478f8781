"""Ready-made scenes: discovery through entry points, typed parameters, building a :class:`Flow`.

A scene is a module-level :class:`Scene` object registered in the entry-point group
``blobflow.scenes`` (see ``pyproject.toml``), so this package never imports ``scenes`` and other
distributions can add scenes of their own::

    [project.entry-points."blobflow.scenes"]
    my_scene = "my_package.my_scene:SCENE"

Its parameters are the keyword arguments of its ``build`` function (each with a default); their
descriptions come from the numpydoc ``Parameters`` section of that function's docstring.
"""

from __future__ import annotations

import inspect
import math
import re
from dataclasses import dataclass
from importlib.metadata import entry_points

from .compose import Flow

__all__ = ["Scene", "Parameter", "available_scenes", "load_scene", "ENTRY_POINT_GROUP"]

ENTRY_POINT_GROUP = "blobflow.scenes"
_TRUE = {"1", "true", "yes", "on"}
_FALSE = {"0", "false", "no", "off"}


@dataclass(frozen=True)
class Parameter:
    """One overridable scene parameter: its name, default value and description."""

    name: str
    default: object
    doc: str = ""

    @property
    def kind(self) -> str:
        """Type name shown to users: bool, int, float, str or vector."""
        d = self.default
        if isinstance(d, bool):
            return "bool"
        if isinstance(d, int):
            return "int"
        if isinstance(d, float):
            return "float"
        if isinstance(d, (tuple, list)):
            return "vector"
        return "str"

    def parse(self, text: str):
        """Convert the string ``text`` (from ``--set``) to this parameter's type."""
        kind = self.kind
        text = text.strip()
        try:
            if kind == "bool":
                if text.lower() in _TRUE:
                    return True
                if text.lower() in _FALSE:
                    return False
                raise ValueError
            if kind == "int":
                return int(text)
            if kind == "float":
                value = float(text)
                if not math.isfinite(value):
                    raise ValueError
                return value
            if kind == "vector":
                values = tuple(float(v) for v in text.strip("()[]").split(","))
                if len(values) != len(self.default) or not all(map(math.isfinite, values)):
                    raise ValueError
                return values
        except ValueError:
            example = {"bool": "true or false", "int": "an integer", "float": "a finite number",
                       "vector": f"{len(self.default) if kind == 'vector' else 3} comma-separated numbers"}
            raise ValueError(
                f"parameter {self.name!r} takes {example[kind]}, got {text!r}"
            ) from None
        return text


def _parameter_docs(func) -> dict[str, str]:
    """First description line of each parameter in a numpydoc ``Parameters`` section."""
    doc = inspect.getdoc(func) or ""
    match = re.search(r"Parameters\n-+\n(.*?)(?:\n\n[A-Z][a-z]+\n-+\n|\Z)", doc, re.S)
    docs: dict[str, str] = {}
    if not match:
        return docs
    current = None
    for line in match.group(1).splitlines():
        head = re.match(r"^(\w+)\s*:", line)
        if head and not line.startswith(" "):
            current = head.group(1)
            docs[current] = ""
        elif current and line.strip() and not docs[current]:
            docs[current] = line.strip()
    return docs


class Scene:
    """A ready-made scene: a function that builds a :class:`Flow` from documented parameters.

    Parameters
    ----------
    name : str
        The name users type (``blobflow run NAME``).
    build : callable
        ``build(**parameters) -> Flow``; every parameter keyword-only with a default.
    description : str
        One line for ``blobflow list``.
    fps : float
        Default frames per second.
    duration : float
        Default simulated seconds.
    """

    def __init__(self, name: str, build, description: str, *, fps: float = 30.0,
                 duration: float = 2.0):
        self.name = name
        self.build_function = build
        self.description = description
        self.fps = float(fps)
        self.duration = float(duration)
        docs = _parameter_docs(build)
        self.parameters: dict[str, Parameter] = {}
        for p in inspect.signature(build).parameters.values():
            if p.default is inspect.Parameter.empty:
                raise TypeError(f"scene {name!r}: parameter {p.name!r} of build() needs a default")
            self.parameters[p.name] = Parameter(p.name, p.default, docs.get(p.name, ""))

    def __repr__(self) -> str:
        return f"Scene({self.name!r}, parameters={list(self.parameters)})"

    def parse_assignments(self, assignments) -> dict:
        """Turn ``["name=value", ...]`` into typed parameters.

        Raises
        ------
        ValueError
            For a malformed assignment, an unknown name (the message lists the valid ones) or a
            value of the wrong type.
        """
        values = {}
        for item in assignments or ():
            if "=" not in item:
                raise ValueError(f"--set takes name=value, got {item!r}")
            key, text = item.split("=", 1)
            key = key.strip()
            if key not in self.parameters:
                raise ValueError(
                    f"scene {self.name!r} has no parameter {key!r}; "
                    f"parameters: {', '.join(self.parameters) or 'none'}"
                )
            values[key] = self.parameters[key].parse(text)
        return values

    def defaults(self) -> dict:
        """Every parameter with its default value."""
        return {name: p.default for name, p in self.parameters.items()}

    def build(self, **parameters) -> Flow:
        """Build the scene's flow with ``parameters`` overriding the defaults."""
        unknown = set(parameters) - set(self.parameters)
        if unknown:
            raise ValueError(
                f"scene {self.name!r} has no parameter {sorted(unknown)[0]!r}; "
                f"parameters: {', '.join(self.parameters) or 'none'}"
            )
        flow = self.build_function(**parameters)
        if not isinstance(flow, Flow):
            raise TypeError(f"scene {self.name!r}: build() must return a Flow, got {type(flow).__name__}")
        return flow


def available_scenes() -> dict[str, object]:
    """Entry points of the installed scenes, by name (loaded lazily)."""
    return {ep.name: ep for ep in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name)}


def load_scene(name: str) -> Scene:
    """Load the scene registered as ``name``.

    Raises
    ------
    ValueError
        If no such scene is installed; the message lists the ones that are.
    """
    scenes = available_scenes()
    if name not in scenes:
        raise ValueError(f"unknown scene {name!r}; scenes: {', '.join(scenes) or 'none installed'}")
    scene = scenes[name].load()
    if not isinstance(scene, Scene):
        raise TypeError(f"entry point {name!r} does not point to a Scene object")
    return scene
