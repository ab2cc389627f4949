"""Typed reading of YAML configuration files, with errors that name the file and the key."""

from __future__ import annotations

import builtins
import math
from pathlib import Path
from typing import Any

import yaml

from footforge.errors import InputError


def read_yaml(path: Path, *, what: str, fix: str) -> Any:
    """Parsed YAML of `path`; a missing file or bad syntax is an InputError."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{what} not found", file=str(path), fix=fix)
    try:
        return yaml.safe_load(path.read_text())
    except yaml.YAMLError as e:
        raise InputError(f"malformed YAML: {e}", file=str(path), fix="fix the YAML syntax") from None


class YamlReader:
    """Typed access to a YAML mapping with errors that name the file and the key path."""

    def __init__(self, data: Any, path: str, file: Path):
        self.data, self.path, self.file = data, path, file

    def fail(self, msg: str, fix: str) -> InputError:
        return InputError(msg, file=str(self.file), element=f"key '{self.path}'" if self.path else "top level", fix=fix)

    def mapping(self) -> dict:
        if not isinstance(self.data, dict):
            raise self.fail(f"expected a mapping, got {type(self.data).__name__}", "write it as 'key: value' lines")
        return self.data

    def check_keys(self, allowed: set[str]) -> YamlReader:
        """This mapping, refused if it holds a key outside `allowed` (a typo would otherwise be
        silently ignored)."""
        unknown = set(self.mapping()) - allowed
        if unknown:
            raise self.fail(f"unknown keys {sorted(unknown)}", f"use only {sorted(allowed)}")
        return self

    def get(self, key: str, default: Any = ...) -> YamlReader:
        """The value under `key` (`default` where it is missing; without one, missing is an error)."""
        m = self.mapping()
        sub = f"{self.path}.{key}" if self.path else key
        if key not in m:
            if default is ...:
                where = f"under '{self.path}' in" if self.path else "to"
                raise YamlReader(None, sub, self.file).fail("missing", f"add '{key}:' {where} {Path(self.file).name}")
            return YamlReader(default, sub, self.file)
        return YamlReader(m[key], sub, self.file)

    def str(self) -> str:
        if not isinstance(self.data, str) or not self.data:
            raise self.fail(f"expected a name, got {self.data!r}", "give a joint or link name")
        return self.data

    def float(self, *, min_value: float | None = None, max_value: float | None = None) -> float:
        if isinstance(self.data, bool) or not isinstance(self.data, (int, float)) or not math.isfinite(self.data):
            raise self.fail(f"expected a finite number, got {self.data!r}", "give a number")
        if min_value is not None and self.data < min_value:
            raise self.fail(f"{self.data} is below {min_value}", f"give a value >= {min_value}")
        if max_value is not None and self.data > max_value:
            raise self.fail(f"{self.data} is above {max_value}", f"give a value <= {max_value}")
        return float(self.data)

    # `builtins.`: in the class body below `def str` and `def float`, those names are the methods.
    def vec3(self) -> tuple[builtins.float, builtins.float, builtins.float]:
        if not isinstance(self.data, list) or len(self.data) != 3:
            raise self.fail(f"expected [x, y, z], got {self.data!r}", "give three numbers")
        x, y, z = (YamlReader(v, f"{self.path}[{i}]", self.file).float() for i, v in enumerate(self.data))
        return x, y, z

    def str_list(self) -> tuple[builtins.str, ...]:
        if not isinstance(self.data, list):
            raise self.fail(f"expected a list of names, got {self.data!r}", "write [a, b]")
        return tuple(YamlReader(v, f"{self.path}[{i}]", self.file).str() for i, v in enumerate(self.data))

    def float_map(self) -> dict[builtins.str, builtins.float]:
        return {str(k): YamlReader(v, f"{self.path}.{k}", self.file).float() for k, v in self.mapping().items()}

    def bool(self) -> bool:
        if not isinstance(self.data, bool):
            raise self.fail(f"expected true or false, got {self.data!r}", "write true or false")
        return self.data
