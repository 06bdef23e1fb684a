"""``behavior-hmm upgrade``: a format 1 model file converted in place or to --out."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_testing import Invoke, assert_user_error, digest
from model_versions import as_version_1


def test_upgrade_converts_a_format_1_file(
    invoke: Invoke, turn_bhmm: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    old = as_version_1(turn_bhmm, tmp_path / "old.bhmm", monkeypatch)
    before = digest(old)
    assert_user_error(invoke(["inspect", old]), "version 1", "behavior-hmm upgrade")
    result = invoke(["upgrade", old, "-o", tmp_path / "new.bhmm"])
    assert result.exit_code == 0, result.output
    assert "from format 1 to 2" in result.output
    assert digest(old) == before  # --out leaves the old file as it was
    assert digest(tmp_path / "new.bhmm") == digest(turn_bhmm)
    result = invoke(["upgrade", old])  # in place
    assert result.exit_code == 0, result.output
    assert digest(old) == digest(turn_bhmm)
    assert invoke(["inspect", old]).exit_code == 0


def test_upgrade_refuses_a_file_that_is_no_model(invoke: Invoke, tmp_path: Path) -> None:
    path = tmp_path / "notes.bhmm"
    path.write_text("not a model\n", encoding="utf-8")
    assert_user_error(invoke(["upgrade", path, "-o", tmp_path / "out.bhmm"]), "notes.bhmm")
    assert not (tmp_path / "out.bhmm").exists()
    assert path.read_text(encoding="utf-8") == "not a model\n"
