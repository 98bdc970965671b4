"""Sphinx configuration of the reachwise documentation.

Built with ``sphinx-build -W --keep-going -n docs OUT`` (``tests/test_docs.py`` does it):
every warning fails the build, every cross-reference must resolve, and nothing is
downloaded (no intersphinx). The file-format, CLI and benchmark references and the
example gallery are generated at build time by ``_ext/reachwise_docs.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
sys.path.insert(0, str(HERE.parent / "src"))

from reachwise._version import __version__  # noqa: E402

project = "reachwise"
author = "reachwise contributors"
copyright = "2026, reachwise contributors"
version = release = __version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "myst_parser",
    "reachwise_docs",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "img/README*"]
myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 3

html_theme = "furo"
html_title = f"reachwise {__version__}"
html_static_path: list[str] = []
# MathJax from its CDN is loaded by the reader's browser, never by the build.

autodoc_member_order = "bysource"
# Signatures are shown without their annotations: many name internal types (a
# scenario's specs, the scene's arrays) that are not part of the public API, and
# nitpicky mode would have to resolve each. Docstrings state types and units.
autodoc_typehints = "none"
# No "show-inheritance" key: autodoc turns a flag option on when its key is present,
# whatever the value ("show-inheritance": False rendered "Bases: ..." under every
# class). Without it, bases are shown only where a directive asks (:show-inheritance:).
autodoc_default_options = {"members": True, "undoc-members": True}
autoclass_content = "class"

nitpicky = True
# External types that appear in our signatures and have no documentation in this build
# (no intersphinx: the build never downloads an inventory). Only names from other
# packages: every reachwise name must resolve.
nitpick_ignore_regex = [
    ("py:.*", r"(numpy|np|numpy\.typing|npt|scipy|pydantic|typer|rich|trimesh|viser|zmq)\..*"),
    ("py:.*", r"(NDArray|ArrayLike|DTypeLike|Array|FloatArray|IntArray|BoolArray)"),
    ("py:.*", r"(pathlib\.)?Path|os\.PathLike|collections\.abc\..*|typing\..*|concurrent\..*"),
    ("py:.*", r"threading\..*|sqlite3\..*|logging\..*|types\..*|enum\..*|io\..*|datetime\..*"),
    ("py:.*", r"difflib\..*"),
    ("py:.*", r"rosbags(\..*)?"),
    ("py:class", r"(float|int|str|bool|bytes|object|dict|list|tuple|set|frozenset|None)"),
    ("py:class", r"(Callable|Iterable|Iterator|Sequence|Mapping|Any|Literal|Self|TypeVar)"),
]
