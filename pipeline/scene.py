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
import re
from importlib.metadata import entry_points
from typing import TYPE_CHECKING

from .assignments import Parameter, parse_assignments
from .compose import Flow

if TYPE_CHECKING:
    from collections.abc import Callable, Iterable
    from typing import Any

__all__ = ["Scene", "Parameter", "available_scenes", "load_scene", "ENTRY_POINT_GROUP"]

ENTRY_POINT_GROUP = "blobflow.scenes"


def _parameter_docs(func) -> dict[str, str]:
    """The description of each parameter in a numpydoc ``Parameters`` section: all its lines
    joined into one, with the reST markup of literals (````x````) removed."""
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
        elif current and line.strip():
            docs[current] = f"{docs[current]} {line.strip()}".strip()
    return {name: " ".join(text.replace("``", "").split()) for name, text in docs.items()}


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
    still : float, optional
        Time (s) of the moment that shows the scene best at its defaults (a cloth draped, a
        jello at rest), drawn by ``blobflow gallery`` and the turntable of ``blobflow run``;
        within ``[0, duration]``.  Default: the most interesting frame
        (:func:`pipeline.render.interesting_frame`: the largest liquid surface, else the
        largest kinetic energy).
    """

    def __init__(self, name: str, build: Callable[..., Flow], description: str, *,
                 fps: float = 30.0, duration: float = 2.0, still: float | None = None):
        self.name = name
        self.build_function = build
        self.description = description
        self.fps = float(fps)
        self.duration = float(duration)
        if still is not None and not 0.0 <= still <= self.duration:
            raise ValueError(f"scene {name!r}: still must be a time in [0, {self.duration:g}] s, "
                             f"got {still!r}")
        self.still = None if still is None else float(still)
        docs = _parameter_docs(build)
        self.parameters: dict[str, Parameter] = {}
        for p in inspect.signature(build).parameters.values():
            if p.default is inspect.Parameter.empty:
                raise TypeError(f"scene {name!r}: parameter {p.name!r} of build() needs a default")
            self.parameters[p.name] = Parameter(p.name, p.default, docs.get(p.name, ""))

    def __repr__(self) -> str:
        return f"Scene({self.name!r}, parameters={list(self.parameters)})"

    def parse_assignments(self, assignments: Iterable[str] | None) -> dict[str, Any]:
        """Turn ``["name=value", ...]`` into typed parameters.

        Raises
        ------
        ValueError
            For a malformed assignment, an unknown name (the message lists the valid ones) or a
            value of the wrong type.
        """
        return parse_assignments(assignments, self.parameters, flag="--set",
                                 owner=f"scene {self.name!r}")

    def defaults(self) -> dict:
        """Every parameter with its default value."""
        return {name: p.default for name, p in self.parameters.items()}

    def build(self, **parameters: Any) -> Flow:
        """Build the scene's flow with ``parameters`` overriding the defaults."""
        unknown = set(parameters) - set(self.parameters)
        if unknown:
            raise ValueError(
                f"scene {self.name!r} has no parameter {sorted(unknown)[0]!r}; "
                f"parameters: {', '.join(self.parameters) or 'none'}"
            )
        flow = self.build_function(**parameters)
        if not isinstance(flow, Flow):
            raise TypeError(f"scene {self.name!r}: build() must return a Flow, "
                            f"got {type(flow).__name__}")
        return flow


def available_scenes() -> dict[str, object]:
    """Entry points of the installed scenes, by name (loaded lazily)."""
    found = sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name)
    return {ep.name: ep for ep in found}


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
