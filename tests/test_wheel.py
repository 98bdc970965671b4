"""The release artefacts: ``python -m build`` makes a wheel and an sdist, and the wheel,
installed into a clean virtual environment (no system site-packages, no access to this
checkout), runs a short job, so that a data file missing from the package shows up.

Marked ``wheel`` (a few minutes): ``pytest -m "not wheel"`` leaves it out."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import pytest

from reachwise._version import __version__

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.wheel


def _run(args: list[str], cwd: Path, env: dict[str, str] | None = None) -> str:
    res = subprocess.run(
        args, cwd=cwd, env=env, capture_output=True, text=True, timeout=1200, check=False
    )
    assert res.returncode == 0, f"{args}:\n{res.stdout[-3000:]}\n{res.stderr[-3000:]}"
    return res.stdout


@pytest.fixture(scope="module")
def dist(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    _run([sys.executable, "-m", "build", "--outdir", str(out), str(ROOT)], cwd=out)
    return out


def _data_files(names: list[str], prefix: str) -> set[str]:
    return {n[len(prefix) :] for n in names if n.startswith(prefix) and not n.endswith("/")}


def test_build_makes_a_wheel_and_an_sdist_with_every_data_file(dist: Path) -> None:
    (wheel,) = dist.glob(f"reachwise-{__version__}-py3-none-any.whl")
    (sdist,) = dist.glob(f"reachwise-{__version__}.tar.gz")
    source = {
        str(p.relative_to(ROOT / "src" / "reachwise" / "data"))
        for p in (ROOT / "src" / "reachwise" / "data").rglob("*")
        if p.is_file() and "__pycache__" not in p.parts
    }
    with zipfile.ZipFile(wheel) as z:
        names = z.namelist()
        meta = z.read(f"reachwise-{__version__}.dist-info/METADATA").decode()
    assert source <= _data_files(names, "reachwise/data/")
    assert "reachwise/py.typed" in names
    assert "Requires-Python: >=3.11" in meta
    assert "Classifier: Programming Language :: Python :: 3.11" in meta
    with tarfile.open(sdist) as t:
        snames = t.getnames()
    assert source <= _data_files(snames, f"reachwise-{__version__}/src/reachwise/data/")


def test_the_wheel_runs_in_a_clean_virtual_environment(dist: Path, tmp_path: Path) -> None:
    (wheel,) = dist.glob("*.whl")
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", str(venv)], cwd=tmp_path)
    py = venv / "bin" / "python"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["MPLBACKEND"] = "Agg"
    _run([str(py), "-m", "pip", "install", "-q", str(wheel)], cwd=tmp_path, env=env)
    work = tmp_path / "work"  # not this checkout: nothing can come from src/
    work.mkdir()
    where = _run([str(py), "-c", "import reachwise; print(reachwise.__file__)"], work, env)
    assert Path(where.strip()).is_relative_to(venv)
    cli = [str(venv / "bin" / "reachwise")]
    assert _run([*cli, "--version"], work, env).strip() == f"reachwise {__version__}"
    # built-in data: a robot, the task, a scenario with its meshes
    data = Path(where.strip()).parent / "data"
    _run([*cli, "robot", "check", str(data / "robots" / "sb60.yaml")], work, env)
    task = json.loads(_run([*cli, "task", "show", "tunnel-87", "--json"], work, env))
    assert task["points"] == 87
    out = work / "sim"
    summary = _run(
        [*cli, "simulate", "p3-self-collision", "--duration", "0.3", "--no-figures",
         "--json", "--out", str(out)], work, env,
    )  # fmt: skip
    assert json.loads(summary)
    assert (out / "report.html").is_file()
