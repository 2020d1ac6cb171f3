import json
import subprocess
import sys
from pathlib import Path

import pytest

from prbdm import cli


@pytest.fixture
def run(capsys):
    """``run(*argv) -> (exit status, stdout, stderr)`` of the ``prbdm`` command, in process."""
    def go(*argv):
        try:
            rc = cli.main(list(map(str, argv)))
        except SystemExit as exc:
            rc = exc.code
        out, err = capsys.readouterr()
        return rc, out, err
    return go


@pytest.fixture(scope="session")
def tiny_set(tmp_path_factory) -> Path:
    """A 12-beam, 2-joint data set and a checkpoint trained on it for a few epochs (all three
    modes), made once per test session in pytest's temporary folder: ROOT/data,
    ROOT/ckpt/beam-n2.safetensors (used by tests/test_surrogate.py and tests/test_cli_predict.py)."""
    from prbdm import dataset as D

    repo = Path(__file__).resolve().parents[1]
    root = tmp_path_factory.mktemp("tiny-surrogate")
    D.generate(root / "data", 12, D.make_spec(joints=2, starts=2, seed=3), workers=0,
               progress="none")
    ckpt = root / "ckpt" / "beam-n2.safetensors"
    run = subprocess.run([sys.executable, str(repo / "training" / "train_surrogate.py"),
                          f"--data={root / 'data'}", f"--out={ckpt}", "--max_epochs=4",
                          "--width=32", "--depth=2", "--quiet=True", "--batch_size=4"],
                         capture_output=True, text=True, cwd=repo, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    return root


@pytest.fixture
def beam_file(tmp_path):
    """``beam_file(data, name="beam.json") -> path``: a beam file in the test's folder (``data``
    a dict written as JSON, or a str written as it is). Some test files define their own, with
    defaults of their own."""
    def write(data, name="beam.json"):
        path = tmp_path / name
        path.write_text(data if isinstance(data, str) else json.dumps(data))
        return str(path)
    return write
