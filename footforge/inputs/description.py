"""Loading robot descriptions: xacro expansion, ROS package resolution, mesh URIs.

A description is a URDF or a xacro file. `$(find pkg)` in xacro and `package://pkg/...` in mesh
URIs resolve through a package path, like ROS_PACKAGE_PATH: a list of folders searched for
`package.xml` files whose `<name>` is the package. The project's own `descriptions/` folder is
always on the path, after the user's folders.
"""

from __future__ import annotations

import contextlib
import io
import os
import xml.parsers.expat
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from footforge.errors import InputError

PACKAGE_URI_PREFIX = "package://"
FILE_URI_PREFIX = "file://"


def descriptions_dir() -> Path:
    """The folder holding the project's own descriptions (source tree or installed package)."""
    source_tree = Path(__file__).resolve().parents[2] / "descriptions"
    if source_tree.is_dir():
        return source_tree
    from importlib import resources

    return Path(str(resources.files("footforge.descriptions")))


def default_foot_description() -> Path:
    return descriptions_dir() / "softfoot_q" / "urdf" / "softfoot_q.urdf.xacro"


def default_robot_description() -> Path:
    return descriptions_dir() / "anymal_c" / "urdf" / "anymal_c.urdf.xacro"


def package_paths_from_env() -> list[Path]:
    value = os.environ.get("ROS_PACKAGE_PATH", "")
    return [Path(p) for p in value.split(os.pathsep) if p]


def resolve_package_paths(user_paths: Sequence[str | Path] = ()) -> list[Path]:
    """The search path: the user's folders, then ROS_PACKAGE_PATH, then the project's own."""
    paths = [Path(p).expanduser().resolve() for p in user_paths]
    for p in paths:
        if not p.is_dir():
            raise InputError(
                "package path is not a folder", file=str(p), fix="pass an existing folder to --package-path"
            )
    paths += [p.resolve() for p in package_paths_from_env() if p.is_dir()]
    paths.append(descriptions_dir())
    return paths


def _package_name(manifest: Path) -> str | None:
    try:
        root = etree.parse(str(manifest)).getroot()
    except etree.XMLSyntaxError:
        return None
    name = root.findtext("name")
    return name.strip() if name else None


def find_package(name: str, package_paths: Sequence[Path]) -> Path:
    """Folder of ROS package `name`: the first folder under the package path whose package.xml
    declares that name (folders are not searched below a package, as rospack does)."""
    for top in package_paths:
        for folder, subdirs, files in os.walk(top):
            if "package.xml" in files:
                if _package_name(Path(folder) / "package.xml") == name:
                    return Path(folder)
                subdirs[:] = []
                continue
            subdirs[:] = sorted(d for d in subdirs if not d.startswith("."))
    searched = ", ".join(str(p) for p in package_paths)
    raise InputError(
        f"cannot find ROS package '{name}' (searched {searched})",
        element=f"package '{name}'",
        fix=f"pass the folder that contains {name}/package.xml with --package-path (or add it to ROS_PACKAGE_PATH)",
    )


@contextlib.contextmanager
def _xacro_find_resolver(package_paths: Sequence[Path]) -> Iterator[None]:
    # xacro's $(find) asks ament_index, which needs a ROS install; swap in our resolver for the
    # duration of one expansion.
    from xacro import substitution_args

    original = substitution_args._eval_find
    substitution_args._eval_find = lambda pkg: str(find_package(pkg, package_paths))
    try:
        yield
    finally:
        substitution_args._eval_find = original


def parse_args(pairs: Sequence[str]) -> dict[str, str]:
    """Parses `NAME:=VALUE` strings (xacro's own syntax) into a mapping."""
    args = {}
    for pair in pairs:
        name, sep, value = pair.partition(":=")
        if not sep or not name:
            raise InputError(f"bad --arg '{pair}'", fix="write it as NAME:=VALUE, e.g. foot:=ball")
        args[name] = value
    return args


def is_xacro(path: Path, text: str) -> bool:
    return path.suffix == ".xacro" or "xmlns:xacro" in text


def expand_xacro(path: Path, *, args: Mapping[str, str] | None = None, package_paths: Sequence[Path] = ()) -> str:
    """Runs xacro on `path` with `args`; returns the URDF text. Errors become InputError."""
    import xacro

    stderr = io.StringIO()
    try:
        with _xacro_find_resolver(package_paths), contextlib.redirect_stderr(stderr):
            doc = xacro.process_file(str(path), mappings=dict(args or {}))
    except InputError:
        raise
    except xml.parsers.expat.ExpatError as e:
        raise InputError(
            f"malformed XML: {e}", file=str(path), fix="fix the XML syntax at that line and column"
        ) from None
    except Exception as e:  # xacro raises XacroException, NameError, KeyError, ArgException...
        detail = stderr.getvalue().strip()
        msg = f"xacro failed: {type(e).__name__}: {e}"
        if detail:
            msg += f" ({detail.splitlines()[-1]})"
        raise InputError(
            msg,
            file=str(path),
            fix="check the macro, property or argument named above; declare "
            "missing arguments with <xacro:arg> or pass them with --arg NAME:=VALUE",
        ) from None
    return doc.toprettyxml(indent="  ")


@dataclass(frozen=True)
class Description:
    """An expanded description: URDF XML plus where it came from."""

    source: Path
    """The xacro or URDF file that was read."""
    urdf: str
    """The URDF text after xacro expansion (mesh URIs as written in the source)."""
    package_paths: tuple[Path, ...]
    """The package search path used to resolve `$(find)` and `package://`."""
    args: Mapping[str, str] = field(default_factory=dict)
    """xacro arguments used for the expansion."""

    def root(self) -> etree._Element:
        return etree.fromstring(self.urdf.encode())

    def resolve_uri(self, uri: str) -> Path:
        return resolve_uri(uri, base_dir=self.source.parent, package_paths=self.package_paths)


def load_description(
    path: str | Path, *, args: Mapping[str, str] | None = None, package_paths: Sequence[str | Path] = ()
) -> Description:
    """Reads a URDF or xacro file into a Description.

    Raises:
      InputError: the file is missing, unreadable, malformed, or xacro fails on it.
    """
    path = Path(path).expanduser()
    if not path.is_file():
        raise InputError("description file not found", file=str(path), fix="pass an existing .urdf or .xacro file")
    paths = tuple(resolve_package_paths(package_paths))
    text = path.read_text()
    args = dict(args or {})
    if is_xacro(path, text):
        urdf = expand_xacro(path.resolve(), args=args, package_paths=paths)
    else:
        if args:
            raise InputError(
                "--arg given for a plain URDF", file=str(path), fix="--arg only applies to xacro files; remove it"
            )
        urdf = text
    try:
        root = etree.fromstring(urdf.encode())
    except etree.XMLSyntaxError as e:
        raise InputError(
            f"malformed XML: {e}", file=str(path), fix="fix the XML syntax at that line and column"
        ) from None
    if root.tag != "robot":
        raise InputError(
            f"root element is <{root.tag}>, not <robot>",
            file=str(path),
            fix="pass a URDF (or a xacro that expands to one)",
        )
    return Description(source=path.resolve(), urdf=urdf, package_paths=paths, args=args)


def resolve_uri(uri: str, *, base_dir: Path, package_paths: Sequence[Path]) -> Path:
    """File path of a URDF mesh URI: package://pkg/rel, file:///abs, absolute or relative path.

    Raises:
      InputError: the package cannot be found.
    """
    if uri.startswith(PACKAGE_URI_PREFIX):
        pkg, _, rel = uri[len(PACKAGE_URI_PREFIX) :].partition("/")
        return find_package(pkg, package_paths) / rel
    if uri.startswith(FILE_URI_PREFIX):
        return Path(uri[len(FILE_URI_PREFIX) :])
    p = Path(uri)
    return p if p.is_absolute() else (base_dir / p)
