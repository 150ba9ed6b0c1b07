"""Layering: the core (protocol, scoring, every dyadbench module) never imports a reference model or a
baseline; the gaze-head layout's adapter and the synthetic gaze generator do not import each other."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "dyadbench"

CORE_RUN = """
import importlib, json, pkgutil, sys
import dyadbench.protocol, dyadbench.scoring
for package in (dyadbench.protocol, dyadbench.scoring):
    for module in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
        importlib.import_module(module.name)
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.runner import evaluate
from tests.protocol_clips import make_source
result = evaluate("zero", make_source(2), ProtocolConfig(context=1), progress=False)
assert result.suite == "dualtalk" and len(result.per_clip) == 4
print(json.dumps(sorted(m for m in sys.modules if m.split(".")[0] in ("models", "baselines"))))
"""


def _imported_modules(path: Path) -> set[str]:
    """Every module an ``import`` or ``from ... import`` statement of ``path`` names, at any depth."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.update([node.module] + [f"{node.module}.{alias.name}" for alias in node.names])
    return names


def test_importing_and_running_the_core_imports_no_model(tmp_path):
    # a fresh interpreter imports every protocol and scoring module and evaluates the zero baseline
    # (streamed, scored with the DualTalk suite): the baseline it asked for is imported, no model
    run = subprocess.run([sys.executable, "-c", CORE_RUN], cwd=ROOT, capture_output=True, text=True, timeout=300,
                         env={"DYADBENCH_CACHE": str(tmp_path), "PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT)})
    assert run.returncode == 0, run.stderr
    imported = json.loads(run.stdout.strip().splitlines()[-1])
    assert "baselines.trivial" in imported and not [m for m in imported if m.split(".")[0] == "models"], imported


@pytest.mark.parametrize("path", sorted(PACKAGE.rglob("*.py")), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_dyadbench_module_imports_a_model_or_baseline(path):
    # models and baselines are reached only through registry strings (dyadbench.registry)
    assert not {m for m in _imported_modules(path) if m.split(".")[0] in ("models", "baselines")}


def test_gaze_layout_and_synthetic_generator_do_not_import_each_other():
    adapter = _imported_modules(PACKAGE / "datasets" / "gaze.py")
    generator = _imported_modules(PACKAGE / "synth" / "gaze.py")
    assert not {m for m in adapter if m.startswith("dyadbench.synth")}
    assert not {m for m in generator if m.startswith("dyadbench.datasets.gaze")}
    # the writer depends on both, one way; the synthetic dataset on the writer
    writer = _imported_modules(PACKAGE / "synth" / "gaze_writer.py")
    assert {"dyadbench.datasets.gaze", "dyadbench.synth.gaze"} <= writer
    assert "dyadbench.synth.gaze_writer" in _imported_modules(PACKAGE / "datasets" / "synthetic_gaze.py")
