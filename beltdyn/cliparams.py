"""Command-line values without pydantic: typer's coercion, its common case done directly.

typer (from 0.2x) coerces every command-line value through a pydantic TypeAdapter built per parameter:
importing pydantic and building the adapters took ~70 ms of every `beltdyn` command (measured on
`beltdyn transient`, issue 10's start-up). beltdyn's parameters are plain: strings, paths, numbers
with a lower bound, lists of strings (and flags, which typer does not coerce). `install` gives those
parameters a coercion that converts a well-formed value itself, as typer's adapter would (a str or a
flag's bool as is, a path by typer's own checks `coerce_cli_path`, a decimal number by float/int and
its bounds),
and hands anything else (a malformed or out-of-range number, any other annotation) to typer's
adapter, so a bad value is refused with typer's own message. Where typer's internals differ,
`install` changes nothing.
"""

from __future__ import annotations

import re
from pathlib import Path

_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")  # decimal: what float() and pydantic read alike
_INTEGER = re.compile(r"[+-]?\d+")
_TYPER = object()  # "typer's adapter decides"


def _plain(descriptor) -> bool:
    """Whether the parameter's values are coerced here: str, Path, float, int, bool or list[str], with
    no parser, choices, clamping or file opening."""
    from typing import get_args, get_origin

    info = descriptor.parameter_info
    if info.parser is not None or descriptor.file_annotation is not None or getattr(info, "clamp", False):
        return False
    ann = descriptor.annotation
    if get_origin(ann) is list:
        return get_args(ann) == (str,)
    return ann in (str, Path, float, int, bool)


def _number(kind: type, text, info):
    """float/int of a well-formed decimal within the parameter's bounds, else _TYPER."""
    if not isinstance(text, str) or not (_NUMBER if kind is float else _INTEGER).fullmatch(text):
        return _TYPER
    x = kind(text)
    if x != x or abs(x) == float("inf"):  # (an exponent beyond the float range: typer's answer)
        return _TYPER
    if (info.min is not None and not x >= info.min) or (info.max is not None and not x <= info.max):
        return _TYPER
    return x


def install() -> None:
    """Coerce beltdyn's plain parameters without pydantic (module docstring). Idempotent."""
    try:
        from typer import core
        from typer._coercion import RuntimeParam, build_runtime_param
        from typer._param_types import coerce_cli_path
    except ImportError:
        return
    cls = getattr(core, "_TyperParameter", None)
    original = getattr(cls, "get_runtime_param", None)
    if original is None or getattr(cls, "_beltdyn_plain", False):
        return

    from typer._click.exceptions import BadParameter

    class Plain(RuntimeParam):
        def _coerce_value(self, value, param, ctx):
            try:
                if isinstance(self.annotation, type):
                    got = self._one(self.annotation, value, param, ctx)
                elif isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value):
                    got = list(value)  # list[str]
                else:
                    got = _TYPER
            except BadParameter:
                raise
            except Exception:  # noqa: BLE001 - typer's internals differ from what this was written for
                got = _TYPER
            if got is _TYPER:
                return build_runtime_param(param.type_descriptor)._coerce_value(value, param=param, ctx=ctx)
            return got

        def _one(self, kind, value, param, ctx):
            if kind is str:
                return value if isinstance(value, str) else _TYPER
            if kind is bool:  # (a flag's own value; a string, from an environment variable: typer's way)
                return value if isinstance(value, bool) else _TYPER
            if kind is Path:
                if not isinstance(value, (str, Path)):
                    return _TYPER
                return Path(coerce_cli_path(value, self.parameter_info, path_type=str, param=param, ctx=ctx))
            return _number(kind, value, self.parameter_info)

    def get_runtime_param(self):
        if getattr(self, "_runtime_param", True) is None:
            try:
                desc = self.type_descriptor
                if _plain(desc):
                    self._runtime_param = Plain(parameter_info=desc.parameter_info, annotation=desc.annotation)
            except Exception:  # noqa: BLE001 - typer's internals differ: its own coercion
                pass
        return original(self)

    cls.get_runtime_param = get_runtime_param
    cls._beltdyn_plain = True
