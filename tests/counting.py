"""Test scaffolding: the calls of one module function counted (`counted`)."""

from typing import Any


def counted(monkeypatch: Any, module: Any, name: str) -> list[tuple]:
    """`module.name` replaced (through `monkeypatch`) by itself counting its calls; the list the
    calls' positional arguments go to."""
    calls: list[tuple] = []
    original = getattr(module, name)

    def counting(*args: Any, **kwargs: Any) -> Any:
        calls.append(args)
        return original(*args, **kwargs)
    monkeypatch.setattr(module, name, counting)
    return calls
