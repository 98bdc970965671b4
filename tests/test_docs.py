"""The documentation builds with every warning an error and every cross-reference
resolved, offline; and what it says is kept true: every public name documented, the
file-format references equal to the models key by key, every command and option in the
CLI reference, every thesis-tour entry importable, every example run."""

from __future__ import annotations

import html
import importlib
import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any, get_args

import pytest
from pydantic import BaseModel

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"

pytestmark = pytest.mark.docs


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The HTML site built with ``sphinx-build -W --keep-going -n`` into a temporary
    folder (never into the source tree)."""
    out = tmp_path_factory.mktemp("docs")
    res = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-n", "-q", "-b", "html",
         "-d", str(out / "doctrees"), str(DOCS), str(out / "html")],
        capture_output=True, text=True, timeout=900, check=False,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr[-6000:]
    assert "WARNING" not in res.stderr, res.stderr[-6000:]
    return out / "html"


def _text(fragment: str) -> str:
    return " ".join(html.unescape(re.sub(r"<[^>]+>", " ", fragment)).split())


def _ids(page: str) -> set[str]:
    return set(re.findall(r'id="(reachwise[\w.]*)"', page))


# ---------------------------------------------------------------- API reference

PUBLIC = ["reachwise", "reachwise.kinematics", "reachwise.tasks", "reachwise.geometry",
          "reachwise.distance", "reachwise.control", "reachwise.planning", "reachwise.report",
          "reachwise.errors", "reachwise.api"]  # fmt: skip


def test_every_public_package_is_in_the_api_reference() -> None:
    """Each subpackage with an ``__all__`` is listed in PUBLIC (a new one must be
    added to docs/api.md and here)."""
    import pkgutil

    import reachwise

    with_all = {
        f"reachwise.{m.name}"
        for m in pkgutil.iter_modules(reachwise.__path__)
        if not m.name.startswith("_")
        and getattr(importlib.import_module(f"reachwise.{m.name}"), "__all__", None)
    }
    assert with_all <= set(PUBLIC)
    text = (DOCS / "api.md").read_text()
    assert [p for p in PUBLIC if f"automodule:: {p}\n" not in text] == []


#: Packages without an ``__all__`` whose modules are documented one by one.
BY_MODULE = ["reachwise.viz", "reachwise.io.ros"]


def test_every_module_of_the_viewer_and_ros_packages_is_in_the_api_reference() -> None:
    import pkgutil

    text = (DOCS / "api.md").read_text()
    missing = [
        f"{package}.{m.name}"
        for package in BY_MODULE
        for m in pkgutil.iter_modules(importlib.import_module(package).__path__)
        if not m.name.startswith("_") and f"automodule:: {package}.{m.name}\n" not in text
    ]
    assert [p for p in BY_MODULE if f"automodule:: {p}\n" not in text] == []
    assert missing == []


def test_classes_are_rendered_without_their_bases(site: Path) -> None:
    """``autodoc_default_options`` has no ``show-inheritance`` key: its presence, even
    as False, turns the flag on, and every class showed a "Bases:" line."""
    assert "Bases:" not in _text((site / "api.html").read_text())


def test_every_public_name_is_documented(site: Path) -> None:
    ids = _ids((site / "api.html").read_text())
    missing = []
    for package in PUBLIC:
        mod = importlib.import_module(package)
        for name in mod.__all__:
            if name == "__version__" or f"{package}.{name}" in ids:
                continue
            obj = getattr(mod, name)
            # a re-export documented where it is defined
            elsewhere = [
                i for i in ids
                if i.rsplit(".", 1)[-1] == name and i.count(".") >= 1
                and getattr(importlib.import_module(i.rsplit(".", 1)[0]), name, None) is obj
            ]  # fmt: skip
            if not elsewhere:
                missing.append(f"{package}.{name}")
    assert missing == []


def test_the_coverage_check_sees_a_missing_name() -> None:
    ids = {"reachwise.kinematics.Robot"}
    assert "reachwise.kinematics.Joint" not in ids  # the check compares exact ids


# ---------------------------------------------------------------- file formats

FORMATS = {
    "reachwise.io.robot_file.RobotModel",
    "reachwise.io.task_file.TaskModel",
    "reachwise.sim.scenarios.ScenarioSpec",
    "reachwise.io.pairs_file._PairsFile",
}


def _model(dotted: str) -> type[BaseModel]:
    module, _, name = dotted.rpartition(".")
    return getattr(importlib.import_module(module), name)  # type: ignore[no-any-return]


def _nested_models(model: type[BaseModel]) -> list[type[BaseModel]]:
    """``model`` and every model reachable from its field annotations."""
    found: list[type[BaseModel]] = []

    def visit(t: Any) -> None:
        if isinstance(t, type) and issubclass(t, BaseModel):
            if t not in found:
                found.append(t)
                for f in t.model_fields.values():
                    visit(f.annotation)
        for a in get_args(t):
            visit(a)

    visit(model)
    return found


def _tables(page: str) -> dict[str, list[list[str]]]:
    """Each rubric's table on a page: rubric -> rows of cell texts (header dropped)."""
    out = {}
    for m in re.finditer(r'<p class="rubric">(.*?)</p>(.*?)</table>', page, re.S):
        rows = re.findall(r"<tr[^>]*>(.*?)</tr>", m.group(2), re.S)
        cells = [[_text(c) for c in re.findall(r"<t[dh][^>]*>(.*?)</t[dh]>", r, re.S)]
                 for r in rows]  # fmt: skip
        out[_text(m.group(1))] = cells[1:]
    return out


def test_file_format_references_equal_the_models(site: Path) -> None:
    tables = _tables((site / "formats.html").read_text())
    for dotted in sorted(FORMATS):
        for model in _nested_models(_model(dotted)):
            rows = {r[0]: r for r in tables[model.__name__]}
            keys = {
                f.alias if isinstance(f.alias, str) else n for n, f in model.model_fields.items()
            }
            assert set(rows) == keys, model.__name__
            for name, info in model.model_fields.items():
                key = info.alias if isinstance(info.alias, str) else name
                _, _type, unit, default, constraints = rows[key]
                assert unit, key
                if info.is_required():
                    assert default == "required", (model.__name__, key)
                else:
                    value = info.get_default(call_default_factory=True)
                    if isinstance(value, BaseModel):
                        value = value.model_dump()
                    assert default == json.dumps(value, default=str), (model.__name__, key)
                for meta in info.metadata:
                    for attr in ("gt", "ge", "lt", "le", "min_length", "max_length"):
                        bound = getattr(meta, attr, None)
                        if bound is not None:
                            shown = f"{bound:g}" if isinstance(bound, float) else str(bound)
                            assert shown in constraints, (model.__name__, key, attr)


def test_every_format_model_is_rendered() -> None:
    text = (DOCS / "formats.md").read_text()
    assert set(re.findall(r"\.\. reachwise-model:: (\S+)", text)) == FORMATS


# ---------------------------------------------------------------- CLI reference


def test_the_cli_reference_has_every_command_and_option(site: Path) -> None:
    import typer
    import typer.main

    from reachwise.cli import app

    page = _text((site / "cli.html").read_text())
    missing = []

    def walk(cmd: Any, path: str) -> None:
        if f"{path} [OPTIONS]" not in page:
            missing.append(path)
        ctx = typer.Context(cmd, info_name=path)
        for p in cmd.get_params(ctx):
            for opt in [*p.opts, *p.secondary_opts]:
                if opt.startswith("-") and opt not in page:
                    missing.append(f"{path} {opt}")
        for name, sub in getattr(cmd, "commands", {}).items():
            walk(sub, f"{path} {name}")

    walk(typer.main.get_command(app), "reachwise")
    assert missing == []


# ---------------------------------------------------------------- thesis tour


def _load(dotted: str) -> Any:
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for attr in parts[i:]:
            obj = getattr(obj, attr)
        return obj
    raise ImportError(dotted)


def test_every_thesis_tour_entry_names_code_that_exists() -> None:
    rows = re.findall(
        r"^\| ([^|]+) \| [^|]+ \| `(reachwise\.[\w.]+)` \|$",
        (DOCS / "thesis-tour.md").read_text(),
        re.M,
    )
    assert len(rows) >= 20
    for equation, dotted in rows:
        obj = _load(dotted)
        assert callable(obj), dotted
        assert "Eq." in equation or "Table" in equation


# ---------------------------------------------------------------- examples


def test_every_example_runs_in_the_build(site: Path) -> None:
    names = sorted(p.stem for p in (ROOT / "examples").glob("*.py"))
    listed = re.findall(r"\{reachwise-example\} (\S+)", (DOCS / "examples.md").read_text())
    assert sorted(listed) == names
    page = (site / "examples.html").read_text()
    assert page.count('src="data:image/png;base64,') >= len(names)
    assert "brute force" in page  # the printed output of closest_points


# ---------------------------------------------------------------- benchmarks


def test_every_benchmark_file_names_its_machine(site: Path) -> None:
    files = sorted((DOCS / "benchmarks").glob("*.json"))
    assert files
    page = _text((site / "benchmarks.html").read_text())
    for f in files:
        run = json.loads(f.read_text())
        assert run["machine"]["cpus"] >= 1 and run["machine"]["python"]
        assert run["benchmark"] in page
        for name in run["targets"]:
            assert name in page


def test_getting_started_lists_every_builtin(site: Path) -> None:
    from importlib import resources

    page = _text((site / "getting-started.html").read_text())
    for kind in ("robots", "tasks", "scenarios"):
        folder = resources.files("reachwise.data") / kind
        names = sorted(f.name[:-5] for f in folder.iterdir() if f.name.endswith(".yaml"))
        line = page[page.index(f"Built-in {kind}:") :].split(".", 1)[0]
        assert [n for n in names if n not in line] == [], kind
