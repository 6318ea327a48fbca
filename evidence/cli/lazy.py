"""Subcommands imported when they are called.

``safecase run``, ``campaign`` and ``train`` need the runtime, the simulator and scipy (about
2 s of imports); ``safecase config check`` or ``audit verify`` need none of it, and neither
should pay for it. :class:`LazyGroup` is the top-level command group: it names every
subcommand from the start (so usage errors, suggestions and ``--help`` are unchanged) and
imports a subcommand's module the first time the subcommand is looked up.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, MutableMapping
from typing import Any, ClassVar

import typer
from typer._click import Command  # typer vendors click; its commands are of this class
from typer.core import TyperGroup

__all__ = ["LazyCommands", "LazyGroup"]


def _load(name: str, module: str, attribute: str) -> Command:
    """The click command of ``module.attribute``: a Typer app (a command group) or a
    command function, named ``name``."""
    target = getattr(importlib.import_module(module), attribute)
    if isinstance(target, typer.Typer):
        command: Command = typer.main.get_group(target)
    else:
        single = typer.Typer()
        single.command(name)(target)
        command = typer.main.get_command(single)
    command.name = name
    return command


class LazyCommands(MutableMapping[str, Command]):
    """A group's commands: the ones built already, and ``lazy`` ones (name -> module,
    attribute) built on first access, in the order eager then lazy."""

    def __init__(
        self, eager: MutableMapping[str, Command], lazy: dict[str, tuple[str, str]]
    ) -> None:
        self._built = dict(eager)
        self._lazy = {k: v for k, v in lazy.items() if k not in self._built}

    def __getitem__(self, name: str) -> Command:
        if name not in self._built:
            if name not in self._lazy:
                raise KeyError(name)
            self._built[name] = _load(name, *self._lazy.pop(name))
        return self._built[name]

    def __setitem__(self, name: str, command: Command) -> None:
        self._lazy.pop(name, None)
        self._built[name] = command

    def __delitem__(self, name: str) -> None:
        if name in self._lazy:
            del self._lazy[name]
        else:
            del self._built[name]

    def __iter__(self) -> Iterator[str]:
        return iter([*self._built, *self._lazy])

    def __len__(self) -> int:
        return len(self._built) + len(self._lazy)

    def __contains__(self, name: object) -> bool:
        return name in self._built or name in self._lazy


class LazyGroup(TyperGroup):
    """A Typer group whose :attr:`lazy` subcommands (name -> module, attribute) are imported
    when first looked up. Subclass it with ``lazy`` set and pass it as ``Typer(cls=...)``."""

    lazy: ClassVar[dict[str, tuple[str, str]]] = {}

    def __init__(self, **attrs: Any) -> None:
        super().__init__(**attrs)
        self.commands = LazyCommands(self.commands, self.lazy)
