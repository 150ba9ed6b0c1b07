"""Run the dyadbench command line in-process as a user would (``main``, its exit code and both streams)."""

from dyadbench.cli import main


def run(capsys, *args) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``dyadbench ARGS`` (arguments converted to strings)."""
    try:
        main([*map(str, args)])
        code = 0
    except SystemExit as exc:
        code = exc.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err
