"""Reading a TOML file and the overrides ``--set KEY=VALUE`` (a dotted key path, the VALUE a TOML
literal, never eval) applied to the parsed TOML before validation."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path
from typing import Any

from beltdyn.errors import ConfigError
from beltdyn.config.kinds import _Checker, _names
from beltdyn.config.schema import DriveConfig


def parse_toml_file(path: Path) -> dict[str, Any]:
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte order mark (some Windows editors) is skipped
    except FileNotFoundError:
        raise ConfigError("file not found", file=str(path)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read: {exc}", file=str(path)) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"TOML syntax error: {exc}", file=str(path)) from None


def _split_key(key: str) -> list[str | int]:
    """'pulleys[1].radius' / 'pulleys.1.radius' / 'pulleys.A.radius' -> ['pulleys', 1, 'radius']."""
    parts: list[str | int] = []
    for piece in key.split("."):
        if not piece:
            raise ValueError("empty key part")
        m = re.fullmatch(r"([^\[\]]+)((?:\[\d+\])*)", piece)
        if not m:
            raise ValueError(f"cannot parse '{piece}'")
        head = m.group(1)
        parts.append(int(head) if head.isdigit() else head)
        parts += [int(i) for i in re.findall(r"\[(\d+)\]", m.group(2))]
    return parts


def _parse_literal(text: str) -> Any:
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_\-]*", text):
            return text  # a bare word is a string
        raise


def apply_override(raw: dict[str, Any], assignment: str, *, file: str) -> None:
    """Apply one ``KEY=VALUE`` override in place (VALUE a TOML literal; never eval). An empty VALUE
    (``KEY=``, what the CLI's ``--unset KEY`` passes) removes the key: ConfigError if it is not there."""
    where = f"--set {assignment}"
    if "=" not in assignment:
        raise ConfigError("expected KEY=VALUE", file=file, key=where)
    key, text = (s.strip() for s in assignment.split("=", 1))
    remove = text == ""
    where = f"--unset {key}" if remove else where
    try:
        parts = _split_key(key)
    except ValueError as exc:
        raise ConfigError(f"bad key '{key}': {exc}", file=file, key=where) from None
    try:
        value = None if remove else _parse_literal(text)
    except tomllib.TOMLDecodeError:
        raise ConfigError(f"value '{text}' is not a TOML literal", file=file, key=where) from None
    node: Any = raw
    for i, part in enumerate(parts[:-1]):
        nxt = parts[i + 1]
        if isinstance(node, list):
            if isinstance(part, str):  # pulleys.A.radius: look up by name
                match = [x for x in node if isinstance(x, dict) and x.get("name") == part]
                if not match:
                    raise ConfigError(f"no entry named '{part}'", file=file, key=where)
                node = match[0]
                continue
            if part >= len(node):
                raise ConfigError(f"index {part} out of range (have {len(node)})", file=file, key=where)
            node = node[part]
            continue
        if not isinstance(node, dict):
            raise ConfigError(f"'{part}' is not a table", file=file, key=where)
        if part not in node:
            if i == 0 and part not in _names(DriveConfig):
                raise _Checker(file).unknown(where, str(part), list(_names(DriveConfig)))
            if remove:
                raise ConfigError(f"no '{part}' in the configuration: nothing to remove", file=file, key=where)
            node[part] = [] if isinstance(nxt, int) else {}
        node = node[part]
    last = parts[-1]
    if isinstance(node, list):
        if not isinstance(last, int) or last >= len(node):
            raise ConfigError(f"bad index '{last}'", file=file, key=where)
        if remove:
            del node[last]
        else:
            node[last] = value
    elif isinstance(node, dict):
        if len(parts) == 1 and last not in _names(DriveConfig):
            raise _Checker(file).unknown(where, str(last), list(_names(DriveConfig)))
        if remove and last not in node:
            raise ConfigError(f"no '{key}' in the configuration: nothing to remove", file=file, key=where)
        if remove:
            del node[last]
        else:
            node[last] = value
    else:
        raise ConfigError(f"'{parts[-2]}' is not a table", file=file, key=where)
