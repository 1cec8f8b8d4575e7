"""The README's commands run as written: every `ale-xfem` command line in its shell blocks
parses (the subcommand, its options, shipped scenes and studies by name), every script it
names exists, and a few cheap ones run from the repository's root without an activated
virtual environment."""

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from ale_xfem.cli import _parser
from ale_xfem.scene import resolve_scene_path
from ale_xfem.studies.accuracy import study_path

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()


def shell_lines() -> list[str]:
    """The commands of the README's ```sh blocks, continuation lines joined, comments cut."""
    lines, block = [], None
    for line in README.splitlines():
        if line.startswith("```"):
            block = [] if line.strip() == "```sh" else None
            continue
        if block is not None:
            lines.append(line)
    joined = "\n".join(lines).replace("\\\n", " ")
    commands = []
    for line in joined.splitlines():
        command = line.split(" # ")[0].strip()
        if command and not command.startswith("#"):
            commands.append(command)
    return commands


# the ale-xfem commands, those launched on several ranks (`.venv/bin/mpiexec -n N ...`) too
LAUNCHED = re.compile(r"^\.venv/bin/mpiexec -n [0-9]+ ")
CLI = [LAUNCHED.sub("", c) for c in shell_lines() if LAUNCHED.sub("", c).startswith(".venv/bin/ale-xfem ")]


def test_the_readme_has_commands_and_names_only_the_venvs_executables():
    assert len(CLI) >= 15
    assert any(LAUNCHED.match(command) for command in shell_lines())  # "Running in parallel"
    for command in shell_lines():
        program = LAUNCHED.sub("", command).split()[0]
        assert program in ("make", ".venv/bin/ale-xfem", ".venv/bin/python"), command


@pytest.mark.parametrize("command", CLI)
def test_every_ale_xfem_command_of_the_readme_parses_and_names_what_exists(command):
    argv = shlex.split(command)[1:]
    args = _parser().parse_args(argv)
    if args.command == "run" and not args.scene.endswith(".toml"):
        assert resolve_scene_path(args.scene).exists()
    if args.command == "study" and args.kind == "accuracy":
        assert study_path(args.target) is not None or resolve_scene_path(args.target).exists()


def test_every_script_the_readme_names_exists():
    scripts = set(re.findall(r"\.venv/bin/python ((?:demos|benchmarks)/[a-z_0-9]+\.py)", README))
    scripts |= {f"demos/{name}.py" for name in re.findall(r"`([a-z_]+)`", README.split("| `demos/` |")[1].split("\n")[0])}
    assert len(scripts) >= 10
    for script in scripts:
        assert (ROOT / script).exists(), script


@pytest.mark.parametrize("command", [
    ".venv/bin/ale-xfem list",
    ".venv/bin/ale-xfem run sod-two-gamma-enriched --explain",
])
def test_cheap_readme_commands_run_from_the_root_as_written(command):
    executable = Path(sys.executable).parent / "ale-xfem"  # the .venv's, as the README writes it
    argv = [str(executable)] + shlex.split(command)[1:]
    done = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert command in README


def test_the_readmes_scene_examples_load_as_written(tmp_path):
    """The scenes of the README's ```toml blocks (a 1D one with every key and its default,
    a 2D one) pass the scene's checks as they are written: a user copies them."""
    from ale_xfem.scene import load_scene

    blocks = re.findall(r"^```toml\n(.*?)^```", README, flags=re.S | re.M)
    assert len(blocks) >= 2
    for k, block in enumerate(blocks):
        path = tmp_path / f"example{k}.toml"
        path.write_text(block)
        load_scene(path)


def test_the_readmes_inline_commands_name_the_venvs_python():
    """Nothing needs activating (README): an inline `python …` would take the system's."""
    assert not re.findall(r"`python3? [^`]*`", README)
