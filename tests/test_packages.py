"""The import names ``rom``/``identify`` are also unrelated PyPI packages: make sure ours are imported."""

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("name", ["rom", "ema", "bladetwin", "identify", "lab"])
def test_package_resolves_to_this_repository(name):
    import importlib
    import importlib.util

    if importlib.util.find_spec(name) is None:
        if (REPO / name).is_dir():
            pytest.fail(f"package {name} exists in the repository but cannot be imported")
        pytest.skip(f"package {name} not created yet")
    mod = importlib.import_module(name)
    assert Path(mod.__file__).resolve().parent == REPO / name


def test_python_dash_m_bladetwin_runs_the_command_line():
    import subprocess
    import sys

    run = subprocess.run([sys.executable, "-m", "bladetwin", "--help"], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("usage: bladetwin") and " run " in run.stdout
    bad = subprocess.run([sys.executable, "-m", "bladetwin", "no-such-command"], capture_output=True, text=True,
                         timeout=120)
    assert bad.returncode == 2 and "invalid choice" in bad.stderr


@pytest.mark.parametrize("name", ["rom", "ema", "bladetwin", "identify", "lab", "bladetwin.stages"])
def test_every_name_in_all_resolves(name):
    import importlib

    mod = importlib.import_module(name)
    missing = [n for n in mod.__all__ if not hasattr(mod, n)]
    assert not missing, f"{name}.__all__ names what it does not have: {missing}"


def test_help_lists_every_command_without_importing_the_numerics():
    """``bladetwin --help`` lists each command's line (the same as its full parser's) and imports no stage."""
    import subprocess
    import sys

    code = ("import sys; from bladetwin.cli import build_parser; build_parser(['--help']); "
            "print(sorted(m for m in ('numpy', 'scipy', 'matplotlib', 'identify', 'rom', 'ema', 'lab') "
            "if m in sys.modules))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=REPO)
    assert run.returncode == 0 and run.stdout.strip() == "[]", (run.stdout, run.stderr)
    from bladetwin.cli import build_parser
    from bladetwin.cli_commands import COMMANDS

    def helps(parser):
        sub = next(a for a in parser._actions if a.dest == "command")
        return {c.dest: c.help for c in sub._choices_actions}

    assert helps(build_parser()) == helps(build_parser(["--help"])) == {k: v[1] for k, v in COMMANDS.items()}
    full = build_parser().parse_args(["lab", "simulate", "--blades", "4"])
    lazy = build_parser(["lab", "simulate", "--blades", "4"]).parse_args(["lab", "simulate", "--blades", "4"])
    assert vars(full) == vars(lazy)  # the command run gets every option it has in the full parser
