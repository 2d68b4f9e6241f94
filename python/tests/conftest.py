"""Shared fixtures: the repository, the CLI binary to compare with."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DRIVE = ROOT / "examples" / "drive_0708.toml"
DRIVE_DATA = ROOT / "data" / "rtklibexplorer-gnss-imu" / "drive_0708"


def _cli():
    explicit = os.environ.get("AIDNAV_CLI")
    if explicit:
        return explicit
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    for profile in ("release", "debug"):
        exe = target / profile / "aidnav"
        if exe.exists():
            return str(exe)
    return shutil.which("aidnav")


@pytest.fixture(scope="session")
def cli_exe():
    """The aidnav CLI (AIDNAV_CLI, or the workspace's build)."""
    exe = _cli()
    if exe is None:
        pytest.fail("no aidnav CLI: build it (cargo build -p aidnav-cli) or set AIDNAV_CLI")
    return exe


@pytest.fixture(scope="session")
def cli(cli_exe):
    """Run the aidnav CLI; fails the test when it fails."""
    exe = cli_exe

    def run(*args):
        done = subprocess.run([exe, *map(str, args)], cwd=ROOT, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        return done

    return run


@pytest.fixture(scope="session")
def drive_cli(cli, tmp_path_factory):
    """The CLI's output directory for the drive example."""
    out = tmp_path_factory.mktemp("drive_cli")
    cli("process", DRIVE, "--out", out)
    return out


@pytest.fixture(scope="session")
def drive_py():
    """The drive example processed from Python."""
    import aidnav

    return aidnav.process(DRIVE)
