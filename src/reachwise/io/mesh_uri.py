"""Mesh file names in robot descriptions resolved the ROS way.

A URDF names its meshes by URI; :func:`resolve_uri` turns one into a file:

- ``package://PKG/rest`` — ``rest`` inside the ROS package ``PKG``, looked for, in
  this order, in
  1. each folder of ``package_dirs`` (the folder itself when it is the package —
     named ``PKG`` or holding a ``package.xml`` that names ``PKG`` — else
     ``folder/PKG``),
  2. each folder of ``ROS_PACKAGE_PATH`` (ROS 1; the same two ways, and one level of
     subfolders named ``PKG``),
  3. ``share/PKG`` under each prefix of ``AMENT_PREFIX_PATH`` (ROS 2),
  4. ``share/PKG`` under the Python environment's prefixes (``sys.prefix`` — conda
     and RoboStack installs — and the ``cmeel.prefix`` folder in site-packages, where
     pip installs packaged ROS descriptions such as ``example-robot-data``),
  5. the robot file's own ancestor folders: one named ``PKG``, or one whose
     ``package.xml`` names ``PKG``;
  6. a folder named ``PKG`` beside the robot file or among the children of any of its
     ancestor folders (pybullet's layout: ``xarm_description/`` next to
     ``xarm6_robot.urdf``), nearest first;
- ``file:///abs/path`` (or ``file://rel/path``, relative to the robot file's folder);
- any other name without a scheme: a path, relative to the robot file's folder.

Other schemes (``http://``, ``model://`` …) are refused: nothing is downloaded. A URI
that cannot be resolved is a :class:`~reachwise.errors.RobotFileError` naming the URI
and every place searched.
"""

from __future__ import annotations

import os
import site
import sys
from collections.abc import Iterable, Sequence
from functools import lru_cache
from pathlib import Path
from urllib.parse import unquote

from reachwise.errors import InputError, RobotFileError
from reachwise.io.xml_tree import read_xml

__all__ = ["package_candidates", "resolve_uri"]

PathLike = str | os.PathLike[str]


@lru_cache(maxsize=256)
def _package_xml_name(folder: str) -> str | None:
    """The ``<name>`` in ``folder/package.xml`` (``None`` when absent or unreadable)."""
    p = Path(folder) / "package.xml"
    if not p.is_file():
        return None
    try:
        root = read_xml(p, str(p))
    except InputError:
        return None
    names = root.findall("name")
    return names[0].text.strip() or None if names else None


def _is_package(folder: Path, pkg: str) -> bool:
    return folder.name == pkg or _package_xml_name(str(folder)) == pkg


def _env_dirs(name: str) -> list[Path]:
    return [Path(p) for p in os.environ.get(name, "").split(os.pathsep) if p]


def _python_prefixes() -> list[Path]:
    out = [Path(sys.prefix)]
    try:
        sites = site.getsitepackages()
    except AttributeError:  # some virtualenv builds lack it
        sites = []
    out += [Path(s) / "cmeel.prefix" for s in sites]
    return out


def package_candidates(
    pkg: str, robot_file: Path | None, package_dirs: Sequence[PathLike] = ()
) -> list[tuple[str, Path]]:
    """Every folder that ``package://PKG`` may name, in search order, each with the rule
    that proposes it (see the module docstring); the folders need not exist."""
    out: list[tuple[str, Path]] = []
    for d in (Path(p) for p in package_dirs):
        out.append(("package_dirs", d if _is_package(d, pkg) else d / pkg))
    for d in _env_dirs("ROS_PACKAGE_PATH"):
        out.append(("ROS_PACKAGE_PATH", d if _is_package(d, pkg) else d / pkg))
        if d.is_dir():
            try:
                subs = sorted(s for s in d.iterdir() if s.is_dir())
            except OSError:
                subs = []
            out += [("ROS_PACKAGE_PATH", s / pkg) for s in subs if (s / pkg).is_dir()]
    for d in _env_dirs("AMENT_PREFIX_PATH"):
        out.append(("AMENT_PREFIX_PATH", d / "share" / pkg))
    for d in _python_prefixes():
        out.append(("Python prefix", d / "share" / pkg))
    if robot_file is not None:
        for a in Path(os.path.abspath(robot_file)).parents:
            if _is_package(a, pkg):
                out.append(("robot file's folders", a))
        out += [
            ("beside the robot file", a / pkg)
            for a in Path(os.path.abspath(robot_file)).parents
            if (a / pkg).is_dir()
        ]
    return out


def resolve_uri(
    uri: str,
    *,
    robot_file: PathLike | None,
    package_dirs: Sequence[PathLike] = (),
    source: str,
    field: str,
    folder: PathLike | None = None,
) -> Path:
    """The file that mesh ``uri`` names (see the module docstring). ``robot_file`` is
    the file the URI was read from (relative paths start at its folder, or at
    ``folder`` when given; its ancestor folders may be the package); errors are
    :class:`RobotFileError` naming ``source`` and ``field``."""
    if not isinstance(uri, str) or not uri.strip():
        raise RobotFileError(source, field, "empty file name")
    rf = None if robot_file is None else Path(robot_file)
    if folder is not None:
        base = Path(folder)
    else:
        base = Path.cwd() if rf is None else Path(os.path.abspath(rf)).parent
    if uri.startswith("package://"):
        rest = unquote(uri[len("package://") :])
        pkg, _, inner = rest.partition("/")
        if not pkg or not inner:
            raise RobotFileError(source, field, f"{uri!r}: expected package://PACKAGE/path")
        found = package_candidates(pkg, rf, package_dirs)
        tried = _dedupe((rule, root / inner) for rule, root in found)
        for _, p in tried:
            if p.is_file():
                return p
        roots = [root for _, root in found if root.is_dir()]
        listing = "; ".join(f"{p} ({rule})" for rule, p in tried) or "nowhere"
        if not roots:
            raise RobotFileError(
                source,
                field,
                f"{uri!r}: unknown package {pkg!r} (pass package_dirs / --package-dir, or set "
                f"ROS_PACKAGE_PATH or AMENT_PREFIX_PATH); searched: {listing}",
            )
        raise RobotFileError(
            source, field, f"{uri!r}: no such file in package {pkg!r}; searched: {listing}"
        )
    if uri.startswith("file://"):
        p = Path(unquote(uri[len("file://") :]))
    elif "://" in uri:
        scheme = uri.split("://", 1)[0]
        raise RobotFileError(
            source,
            field,
            f"{uri!r}: scheme {scheme}:// is not supported (package://, file://, "
            "or a path); nothing is downloaded",
        )
    else:
        p = Path(uri)
    full = p if p.is_absolute() else base / p
    if not full.is_file():
        raise RobotFileError(source, field, f"{uri!r}: no such file; searched: {full}")
    return full


def _dedupe(items: Iterable[tuple[str, Path]]) -> list[tuple[str, Path]]:
    seen: set[str] = set()
    out = []
    for rule, p in items:
        key = os.path.normpath(str(p))
        if key not in seen:
            seen.add(key)
            out.append((rule, p))
    return out
