"""The generated reference pages of docs/ are what docs/generate.py writes today: regenerate them
into a temporary folder and compare with the committed ones (run `python docs/generate.py` after
changing a command's arguments or a shipped checkpoint)."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PAGES = ("commands.md", "checkpoints.md")


def _generate():
    spec = importlib.util.spec_from_file_location("docs_generate", REPO / "docs" / "generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("page", PAGES)
def test_generated_reference_pages_are_current(tmp_path, page):
    _generate().write(tmp_path)
    committed = (REPO / "docs" / "reference" / page).read_text()
    fresh = (tmp_path / page).read_text()
    assert committed == fresh, (f"docs/reference/{page} is stale: run `python docs/generate.py` "
                                "and commit the result")


def test_every_command_is_on_the_commands_page():
    from prbdm.cli import COMMANDS

    text = (REPO / "docs" / "reference" / "commands.md").read_text()
    for name in COMMANDS:
        assert f"## prbdm {name}\n" in text, name


def test_docs_links_resolve():
    """Every relative link of README.md and docs/**/*.md names a file that exists."""
    import re

    pages = [REPO / "README.md", *(REPO / "docs").rglob("*.md")]
    missing = []
    for page in pages:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text()):
            if "://" in target or target.startswith("mailto:"):
                continue
            if not (page.parent / target).exists():
                missing.append(f"{page.relative_to(REPO)} -> {target}")
    assert not missing, missing
