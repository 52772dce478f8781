"""``NAME=VALUE`` assignments from the command line, typed by the parameter they set.

One parser for ``blobflow run --set`` (scene parameters) and ``blobflow surface --option``
(surface options): a :class:`Parameter` knows its type (from its default, or given), and
:func:`parse_assignments` turns ``["name=value", ...]`` into typed values. Booleans are written
``true``/``yes``/``on``/``1`` or ``false``/``no``/``off``/``0`` (:data:`TRUE_WORDS`,
:data:`FALSE_WORDS`), vectors as comma-separated numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Iterable
    from typing import Any

__all__ = ["Parameter", "parse_assignments", "TRUE_WORDS", "FALSE_WORDS", "KINDS"]

#: Words read as True and as False (case-insensitive).
TRUE_WORDS = frozenset({"1", "true", "yes", "on"})
FALSE_WORDS = frozenset({"0", "false", "no", "off"})
#: Types a parameter can have (``names``: a comma-separated list of names).
KINDS = ("bool", "int", "float", "str", "vector", "names")


@dataclass(frozen=True)
class Parameter:
    """One parameter that an assignment can set: its name, default value, description and type.

    ``kind`` is one of :data:`KINDS`; when omitted it follows the default (bool, int, float,
    str, or a vector of as many numbers as the default has).
    """

    name: str
    default: object
    doc: str = ""
    kind: str | None = None

    def __post_init__(self):
        if self.kind is None:
            d = self.default
            kind = ("bool" if isinstance(d, bool) else "int" if isinstance(d, int)
                    else "float" if isinstance(d, float)
                    else "vector" if isinstance(d, (tuple, list)) else "str")
            object.__setattr__(self, "kind", kind)
        elif self.kind not in KINDS:
            raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {self.kind!r}")

    def parse(self, text: str) -> Any:
        """Convert the string ``text`` to this parameter's type.

        Raises
        ------
        ValueError
            Naming the parameter and what it takes.
        """
        kind = self.kind
        text = text.strip()
        size = len(self.default) if isinstance(self.default, (tuple, list)) else 3
        try:
            if kind == "bool":
                if text.lower() in TRUE_WORDS:
                    return True
                if text.lower() in FALSE_WORDS:
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
                if len(values) != size or not all(map(math.isfinite, values)):
                    raise ValueError
                return values
            if kind == "names":
                names = tuple(v.strip() for v in text.split(",") if v.strip())
                if not all(n.isidentifier() for n in names):
                    raise ValueError
                return names
        except ValueError:
            example = {"bool": "true or false", "int": "an integer", "float": "a finite number",
                       "vector": f"{size} comma-separated numbers",
                       "names": "comma-separated names"}[kind]
            raise ValueError(f"parameter {self.name!r} takes {example}, got {text!r}") from None
        return text


def parse_assignments(items: Iterable[str] | None, parameters: dict[str, Parameter], *,
                      flag: str = "--set", owner: str = "") -> dict[str, Any]:
    """Turn ``["name=value", ...]`` into ``{name: typed value}``.

    Parameters
    ----------
    items : iterable of str
        The assignments, in order (a later one wins).
    parameters : dict of str to Parameter
        What may be set.
    flag : str
        The command-line flag, for messages.
    owner : str
        What the parameters belong to, for messages (e.g. ``scene 'drop'``).

    Raises
    ------
    ValueError
        For a malformed assignment, an unknown name (the message lists the valid ones) or a
        value of the wrong type.
    """
    values = {}
    for item in items or ():
        if "=" not in item:
            raise ValueError(f"{flag} takes name=value, got {item!r}")
        key, text = item.split("=", 1)
        key = key.strip().replace("-", "_")
        if key not in parameters:
            where = f"{owner} has no parameter {key!r}" if owner else f"no parameter {key!r}"
            raise ValueError(f"{where}; parameters: {', '.join(parameters) or 'none'}")
        values[key] = parameters[key].parse(text)
    return values
