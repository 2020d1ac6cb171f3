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
