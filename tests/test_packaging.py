"""The wheel carries every subpackage and the shipped checkpoints (pyproject.toml lists them)."""
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
import tomllib

ROOT = Path(__file__).resolve().parents[1]


def _config():
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]


def test_every_subpackage_is_listed():
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "prbdm").rglob("__init__.py")}
    listed = set(_config()["packages"])
    assert found <= listed, f"add to pyproject.toml [tool.setuptools] packages: {found - listed}"
    assert _config()["package-dir"]["prbdm.checkpoints"] == "checkpoints"


def test_shipped_checkpoints_are_found_from_a_checkout():
    from prbdm import surrogate as sg
    names = {p.name for p in sg.available_checkpoints()}
    assert {"beam-n3.safetensors", "beam-n4.safetensors", "beam-n5.safetensors"} <= names


@pytest.mark.slow
def test_wheel_contains_the_checkpoints_and_no_logs(tmp_path):
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation",
                    str(ROOT), "-w", str(tmp_path)], check=True)
    names = zipfile.ZipFile(next(tmp_path.glob("*.whl"))).namelist()
    assert "prbdm/checkpoints/beam-n4.safetensors" in names
    assert "prbdm/checkpoints/beam-n4.json" in names
    assert not [n for n in names if n.endswith(".log")]
