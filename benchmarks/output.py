"""The result files of the benchmark scripts: one JSON and one Markdown file per run, written as a set.

Every script in this folder ends with :func:`write_result`, which writes ``NAME.json`` and ``NAME.md``
(by default into ``benchmarks/results/``) atomically and together (:func:`dyadbench.atomic.write_texts`:
both complete, or both as they were). The JSON file holds

- ``benchmark``: the script's file name;
- ``command``: the command line that regenerates the file (``python benchmarks/<script> ARGS``);
- ``seed``: the seed the run used (``null`` where nothing in it is random);
- ``machine``: CPU cores, platform, Python and library versions, thread settings
  (:func:`machine_facts`);
- ``markdown``: the script's tables and notes as Markdown (the body of the ``.md`` file);
- ``data``: the numbers behind the tables, where the script passes them.

``dyadbench report`` reads the JSON files into ``RESULTS.md``; nothing in it is pasted by hand. No
timestamp is recorded, so a re-run on the same machine with the same numbers writes the same bytes.
"""

from __future__ import annotations

import os
import platform
import shlex
import sys
from importlib import metadata
from pathlib import Path
from typing import Any

from dyadbench import atomic

#: Where the committed benchmark result files live.
RESULTS = Path(__file__).resolve().parent / "results"
ROOT = Path(__file__).resolve().parents[1]
#: Libraries whose versions can change a benchmark's numbers or timings (read from the installed
#: distributions' metadata, so recording them imports nothing).
LIBRARIES = ("numpy", "scipy", "numba", "torch", "scikit-learn", "pandas")
#: Environment variables that set the number of threads of the numeric libraries.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")


def machine_facts() -> dict[str, Any]:
    """Cores, platform, Python and library versions and thread settings of this process.

    ``torch_threads`` / ``numba_threads`` are read only from libraries the script has already imported.
    """
    versions = {}
    for name in LIBRARIES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    threads: dict[str, Any] = {v: os.environ.get(v) for v in THREAD_VARIABLES}
    if "torch" in sys.modules:
        threads["torch_threads"] = sys.modules["torch"].get_num_threads()
    if "numba" in sys.modules:
        threads["numba_threads"] = sys.modules["numba"].get_num_threads()
    return {"cpu_count": os.cpu_count(), "usable_cores": len(os.sched_getaffinity(0)),
            "platform": f"{platform.system()} {platform.machine()}", "python": platform.python_version(),
            "versions": versions, "threads": threads}


def command_line(argv: list[str] | None = None) -> str:
    """``python <script> ARGS`` for ``argv`` (default ``sys.argv``), the script relative to the repository."""
    argv = list(sys.argv if argv is None else argv)
    script = Path(argv[0]).resolve()
    shown = script.relative_to(ROOT) if script.is_relative_to(ROOT) else Path(argv[0])
    return shlex.join(["python", str(shown), *argv[1:]])


class Transcript:
    """What a script prints, kept line by line for its result file: ``say`` prints and records."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def say(self, text: str = "") -> None:
        print(text)
        self.lines.extend(text.split("\n"))

    def text(self) -> str:
        return "\n".join(self.lines).strip("\n")


def preformatted(title: str, text: str) -> str:
    """Markdown of a plain-text table: a ``# title`` heading and the text in a fenced block."""
    return f"# {title}\n\n```\n{text.strip(chr(10))}\n```\n"


def result_paths(out: str | Path) -> tuple[Path, Path]:
    """(JSON, Markdown) paths of a result named by ``out`` (``NAME``, ``NAME.md`` or ``NAME.json``)."""
    out = Path(out)
    stem = out.with_suffix("") if out.suffix in (".md", ".json") else out
    return stem.with_name(stem.name + ".json"), stem.with_name(stem.name + ".md")


def render_markdown(record: dict[str, Any]) -> str:
    """The ``.md`` file of a result record: its Markdown, then how to regenerate it and where it ran."""
    machine = record["machine"]
    versions = ", ".join(f"{k} {v}" for k, v in machine["versions"].items() if v is not None)
    threads = ", ".join(f"{k}={v}" for k, v in machine["threads"].items() if v is not None) or "defaults"
    return (record["markdown"].rstrip("\n") + "\n\n---\n"
            f"Regenerate: `{record['command']}` (seed {record['seed']})  \n"
            f"Machine: {machine['usable_cores']} of {machine['cpu_count']} cores usable, {machine['platform']}, "
            f"Python {machine['python']}; {versions}; threads: {threads}\n")


def write_result(out: str | Path, markdown: str, *, seed: int | list[int] | None, data: Any = None,
                 argv: list[str] | None = None) -> tuple[Path, Path]:
    """Write a benchmark's result as ``NAME.json`` and ``NAME.md`` beside each other, as one set.

    ``out`` names the result (see :func:`result_paths`); ``markdown`` is the script's tables and notes;
    ``seed`` the seed it used (None if nothing is random); ``data`` optional JSON-able numbers.
    Returns (JSON path, Markdown path).
    """
    json_path, md_path = result_paths(out)
    record = {"benchmark": Path((argv or sys.argv)[0]).name, "command": command_line(argv), "seed": seed,
              "machine": machine_facts(), "markdown": markdown.rstrip("\n") + "\n", "data": data}
    atomic.write_texts({json_path: atomic.to_json(record), md_path: render_markdown(record)})
    return json_path, md_path


def write_cache_entry(path: str | Path, data: Any) -> Path:
    """Write one finished run of a benchmark's ``--cache`` folder (JSON, atomically): an intermediate that
    lets a rerun skip the run, never a result (results go through :func:`write_result`)."""
    atomic.write_json(path, data)
    return Path(path)
