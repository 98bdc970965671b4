"""Sphinx directives that generate parts of the reachwise documentation at build time.

- ``reachwise-model`` — the reference of a file format from its pydantic model: every
  key (nested models in sections of their own), its type, unit, default and
  constraints. :func:`model_sections` is what the directive renders and what
  ``tests/test_docs.py`` compares with the models.
- ``reachwise-cli`` — the command-line reference from the typer app: every command with
  its usage line, help text and every argument and option.
- ``reachwise-bench`` — the benchmark table from the ``reachwise bench … --json`` files in
  ``docs/benchmarks/``, each naming the machine it ran on.
- ``reachwise-builtins`` — the built-in robots, tasks and scenarios, from the data folder.
- ``reachwise-example`` — runs ``examples/NAME.py`` (its argument is an output folder) and
  embeds its printed output and the PNG figures it wrote; an example that fails fails
  the build.
"""

from __future__ import annotations

import base64
import json
import os
import subprocess
import sys
import tempfile
import types
from dataclasses import dataclass
from importlib import import_module
from pathlib import Path
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from docutils import nodes
from docutils.statemachine import StringList
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined
from sphinx.application import Sphinx
from sphinx.errors import ExtensionError
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

ROOT = Path(__file__).resolve().parents[2]

# ---------------------------------------------------------------- file formats


#: Units of file keys by name (SI; degrees only where the key says ``_deg``).
UNITS: dict[str, str] = {
    "a": "m",
    "d": "m",
    "alpha": "rad",
    "theta": "rad",
    "xyz": "m",
    "rpy": "rad",
    "dt": "s",
    "duration": "s",
    "monitor": "s",
    "contact_check": "s",
    "margin": "m",
    "latency": "s",
    "rate": "1/s",
    "near": "m",
    "far": "m",
    "fov": "rad",
    "voxel": "m",
    "noise": "1/m",
    "speed": "m/s",
    "radius": "m",
    "size": "m",
    "width": "m",
    "height": "m",
    "offset": "m",
    "position": "m",
    "depth": "m",
    "work": "s",
    "time": "s",
    "t": "s",
    "tolerance": "m",
    "min_length": "m",
    "vmax": "m/s or rad/s",
    "limits": "m or rad",
    "look_at": "m",
    "distance": "m",
    "distances": "m",
    "clearance": "m",
    "period": "s",
    "velocity": "m/s",
    "extent": "m",
    "center": "m",
    "half": "m",
    "start": "s",
    "end": "s",
}


def unit_of(key: str) -> str:
    """The unit of file key ``key``: ``deg`` (``deg/s``) for ``…_deg`` keys, else
    :data:`UNITS`, else ``—``."""
    if key.startswith("vmax_deg"):
        return "deg/s"
    if key.endswith("_deg") or "_deg_" in key:
        return "deg"
    return UNITS.get(key, "—")


@dataclass(frozen=True)
class FieldRow:
    """One key of a file format as the reference shows it."""

    key: str
    type: str
    required: bool
    default: str
    constraints: str
    unit: str


@dataclass(frozen=True)
class ModelSection:
    """One model of a file format and its keys."""

    name: str
    rows: tuple[FieldRow, ...]


def _members(annotation: Any) -> list[Any]:
    origin = get_origin(annotation)
    if origin is Annotated:
        return _members(get_args(annotation)[0])
    if origin is Union or origin is types.UnionType:
        return [m for a in get_args(annotation) for m in _members(a)]
    return [annotation]


def _is_model(t: Any) -> bool:
    return isinstance(t, type) and issubclass(t, BaseModel)


def type_text(annotation: Any) -> str:
    """A type as a file's reader thinks of it: ``number``, ``list of Joint``,
    ``"revolute" | "prismatic"``, ``[number, number]``."""
    if annotation is None or annotation is type(None):
        return "null"
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is Annotated:
        return type_text(args[0])
    if origin is Union or origin is types.UnionType:
        return " | ".join(dict.fromkeys(type_text(a) for a in args))
    if origin is Literal:
        return " | ".join(json.dumps(a) for a in args)
    if origin in (list, set, frozenset):
        return f"list of {type_text(args[0])}" if args else "list"
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return f"list of {type_text(args[0])}"
        return "[" + ", ".join(type_text(a) for a in args) + "]"
    if origin is dict:
        return f"mapping of {type_text(args[0])} to {type_text(args[1])}" if args else "mapping"
    if _is_model(annotation):
        return annotation.__name__
    names = {float: "number", int: "integer", str: "string", bool: "boolean", Any: "any"}
    if annotation in names:
        return names[annotation]
    return getattr(annotation, "__name__", str(annotation))


_BOUNDS = {"gt": ">", "ge": "≥", "lt": "<", "le": "≤", "min_length": "length ≥",
           "max_length": "length ≤", "multiple_of": "multiple of"}  # fmt: skip


def constraints_text(info: FieldInfo) -> str:
    """The constraints pydantic checks on a field: ``> 0``, ``length ≥ 1``."""
    out = []
    for meta in info.metadata:
        for attr, sign in _BOUNDS.items():
            value = getattr(meta, attr, None)
            if value is not None:
                out.append(f"{sign} {value:g}" if isinstance(value, float) else f"{sign} {value}")
    return ", ".join(out)


def default_text(info: FieldInfo) -> str:
    if info.is_required():
        return ""
    if info.default_factory is not None:
        value = info.default_factory()  # type: ignore[call-arg]
    else:
        value = info.default
    if value is PydanticUndefined:
        return ""
    if isinstance(value, BaseModel):
        value = value.model_dump()
    return json.dumps(value, default=str)


def field_key(name: str, info: FieldInfo) -> str:
    """The key as written in a file (the alias where the model has one)."""
    return info.alias if isinstance(info.alias, str) else name


def model_sections(model: type[BaseModel]) -> list[ModelSection]:
    """``model`` and every model nested in it (first seen first), with their keys."""
    seen: list[type[BaseModel]] = []
    todo = [model]
    while todo:
        m = todo.pop(0)
        if m in seen:
            continue
        seen.append(m)
        for info in m.model_fields.values():
            todo += [t for t in _nested(info.annotation) if t not in seen]
    return [
        ModelSection(
            m.__name__,
            tuple(
                FieldRow(
                    key=field_key(name, info),
                    type=type_text(info.annotation),
                    required=info.is_required(),
                    default=default_text(info),
                    constraints=constraints_text(info),
                    unit=unit_of(field_key(name, info)),
                )
                for name, info in m.model_fields.items()
            ),
        )
        for m in seen
    ]


def _nested(annotation: Any) -> list[type[BaseModel]]:
    out: list[type[BaseModel]] = []
    for t in _members(annotation):
        if _is_model(t):
            out.append(t)
        else:
            for a in get_args(t):
                if a is not Ellipsis:
                    out += _nested(a)
    return out


def _cell(text: str) -> str:
    return f"``{text}``" if text else ""


def model_rst(model: type[BaseModel]) -> list[str]:
    lines: list[str] = []
    for section in model_sections(model):
        lines += [
            f".. rubric:: {section.name}",
            "",
            ".. list-table::",
            "   :header-rows: 1",
            "",
            "   * - key",
            "     - type",
            "     - unit",
            "     - default",
            "     - constraints",
        ]
        for r in section.rows:
            lines += [
                f"   * - ``{r.key}``",
                f"     - {_cell(r.type)}",
                f"     - {r.unit}",
                f"     - {'**required**' if r.required else _cell(r.default)}",
                f"     - {r.constraints}",
            ]
        lines.append("")
    return lines


def import_name(dotted: str) -> Any:
    module, _, name = dotted.rpartition(".")
    return getattr(import_module(module), name)


class _Generated(SphinxDirective):
    """A directive whose content is reST generated by :meth:`lines`."""

    def lines(self) -> list[str]:
        raise NotImplementedError

    def run(self) -> list[nodes.Node]:
        node = nodes.section()
        node.document = self.state.document
        nested_parse_with_titles(self.state, StringList(self.lines(), "<generated>"), node)
        return list(node.children)


class ModelDirective(_Generated):
    required_arguments = 1

    def lines(self) -> list[str]:
        return model_rst(import_name(self.arguments[0]))


# ---------------------------------------------------------------- command line


def cli_commands() -> list[tuple[str, Any]]:
    """Every command of ``reachwise`` (groups included) as (path, click command)."""
    import typer.main

    from reachwise.cli import app

    out: list[tuple[str, Any]] = []

    def walk(cmd: Any, path: str) -> None:
        out.append((path, cmd))
        for name, sub in sorted(getattr(cmd, "commands", {}).items()):
            walk(sub, f"{path} {name}")

    walk(typer.main.get_command(app), "reachwise")
    return out


def _param_row(param: Any) -> list[str]:
    names = ", ".join([*param.opts, *param.secondary_opts])
    if param.param_type_name == "argument":
        names = (param.metavar or param.name).upper()
    help_text = " ".join((getattr(param, "help", None) or "").split())
    default = param.default
    shown = "" if default is None or param.required or callable(default) else repr(default)
    if isinstance(default, bool) and param.param_type_name == "option" and param.is_flag:
        shown = "on" if default else "off"
    return [f"``{names}``", help_text.replace("*", r"\*"), f"``{shown}``" if shown else ""]


def cli_rst() -> list[str]:
    import typer

    from reachwise.cli._help import usage_pieces

    lines: list[str] = []
    for path, cmd in cli_commands():
        ctx = typer.Context(cmd, info_name=path)
        lines += [path, "-" * len(path), "", ".. code-block:: text", ""]
        lines += ["   " + " ".join([path, *usage_pieces(cmd, ctx)]), ""]
        doc = (cmd.help or "").replace("``", "").replace("\b", "")
        lines += [".. code-block:: text", ""]
        lines += ["   " + ln for ln in doc.strip().splitlines()] + [""]
        params = [p for p in cmd.get_params(ctx) if not getattr(p, "hidden", False)]
        if params:
            lines += [".. list-table::", "   :header-rows: 1", "   :widths: 25 60 15", ""]
            lines += ["   * - argument or option", "     - meaning", "     - default"]
            for p in params:
                a, b, c = _param_row(p)
                lines += [f"   * - {a}", f"     - {b}", f"     - {c}"]
            lines.append("")
    return lines


class CliDirective(_Generated):
    def lines(self) -> list[str]:
        return cli_rst()


# ---------------------------------------------------------------- benchmarks


def bench_rows(folder: Path) -> list[dict[str, Any]]:
    """The runs in ``folder/*.json`` (``reachwise bench NAME --json`` output), each with
    its file name."""
    runs = []
    for f in sorted(folder.glob("*.json")):
        data = json.loads(f.read_text())
        data["_file"] = f.name
        runs.append(data)
    return runs


def _fmt(v: Any) -> str:
    if v is None:
        return "—"
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, dict):
        return ", ".join(f"{k} {_fmt(x)}" for k, x in v.items())
    return str(v)


def machine_text(machine: dict[str, Any]) -> str:
    """One line naming the machine a benchmark ran on."""
    return ", ".join(f"{k} {v}" for k, v in machine.items())


def bench_table(run: dict[str, Any]) -> list[tuple[str, str, str, str]]:
    """(figure, value, target, met) rows of one ``reachwise bench --json`` run: its
    targets first, then every median and ratio."""
    rows = []
    for name, t in run.get("targets", {}).items():
        met = "yes" if t.get("met") else "**no**"
        rows.append((name, _fmt(t.get("value")), f"≤ {_fmt(t.get('limit'))}", met))
    for name, v in run.get("metrics", {}).items():
        if name.endswith(".median"):
            rows.append((name, _fmt(v), "", ""))
    for name, v in run.get("ratios", {}).items():
        rows.append((name, _fmt(v), "", ""))
    return rows


class BenchDirective(_Generated):
    def lines(self) -> list[str]:
        folder = Path(self.env.srcdir) / "benchmarks"
        runs = bench_rows(folder)
        if not runs:
            raise ExtensionError(f"no benchmark JSON files in {folder}")
        lines: list[str] = []
        for run in runs:
            machine = run.get("machine")
            if not machine:
                raise ExtensionError(f"{run['_file']} does not name the machine it ran on")
            self.env.note_dependency(str(folder / run["_file"]))
            lines += [f".. rubric:: {run.get('benchmark', run['_file'])}", ""]
            lines += [f"Machine: {machine_text(machine)}.", ""]
            lines += [".. list-table::", "   :header-rows: 1", "", "   * - figure",
                      "     - value", "     - target", "     - met"]  # fmt: skip
            for fig, value, target, met in bench_table(run):
                lines += [f"   * - ``{fig}``", f"     - {value}", f"     - {target}",
                          f"     - {met}"]  # fmt: skip
            notes = run.get("notes") or []
            lines.append("")
            for n in notes:
                lines += [f"- {' '.join(str(n).split())}".replace("*", r"\*")]
            lines.append("")
        return lines


# ---------------------------------------------------------------- examples


class ExampleDirective(SphinxDirective):
    """Run ``examples/NAME.py OUT`` and embed its source, output and figures."""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        name = self.arguments[0]
        script = ROOT / "examples" / f"{name}.py"
        if not script.is_file():
            raise ExtensionError(f"example {script} not found")
        self.env.note_dependency(str(script))
        with tempfile.TemporaryDirectory() as out:
            env = {**os.environ, "MPLBACKEND": "Agg"}
            env["PYTHONPATH"] = os.pathsep.join(
                [str(ROOT / "src"), *filter(None, [os.environ.get("PYTHONPATH")])]
            )
            res = subprocess.run(
                [sys.executable, str(script), out], capture_output=True, text=True, env=env,
                timeout=600, check=False,
            )  # fmt: skip
            if res.returncode != 0:
                raise ExtensionError(f"example {name} failed:\n{res.stderr[-3000:]}")
            figures = sorted(Path(out).glob("*.png"))
            images = [base64.b64encode(f.read_bytes()).decode() for f in figures]
        source = script.read_text()
        out_nodes: list[nodes.Node] = [
            nodes.literal_block(source, source, language="python"),
        ]
        if res.stdout.strip():
            out_nodes.append(nodes.paragraph(text="Output:"))
            out_nodes.append(nodes.literal_block(res.stdout, res.stdout, language="text"))
        for fig, data in zip(figures, images, strict=True):
            html = f'<img src="data:image/png;base64,{data}" alt="{fig.name}" width="100%"/>'
            out_nodes.append(nodes.raw("", html, format="html"))
        return out_nodes


class BuiltinsDirective(_Generated):
    """The built-in robots, tasks and scenarios, read from ``reachwise/data``."""

    def lines(self) -> list[str]:
        from reachwise.io._builtin import builtin_names

        lines: list[str] = []
        for kind in ("robots", "tasks", "scenarios"):
            names = ", ".join(f"``{n}``" for n in builtin_names(kind))
            lines.append(f"- Built-in {kind}: {names}.")
        return [*lines, ""]


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_directive("reachwise-builtins", BuiltinsDirective)
    app.add_directive("reachwise-model", ModelDirective)
    app.add_directive("reachwise-cli", CliDirective)
    app.add_directive("reachwise-bench", BenchDirective)
    app.add_directive("reachwise-example", ExampleDirective)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
