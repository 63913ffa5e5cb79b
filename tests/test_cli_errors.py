"""The command line's errors of usage and environment: one line on stderr, exit status 2, no traceback; and
`cache clear` says what it would remove and asks first.

Every case is checked against the file system itself (what exists before and after), not against dfloop's own
listing. Subprocess runs (the real console entry, real stdin) where stdin or the process matter; main() in
process where a failure must be injected (a read-only cache: the suite may run as root, which no permission
bit stops, so removal is made to fail with the PermissionError a read-only directory gives).
"""
import io
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dfloop.cli import main

ROOT = Path(__file__).resolve().parents[1]


def run_cli(*args, env=None, stdin=subprocess.DEVNULL):
    """`python -m dfloop.cli ARGS` in a subprocess: (exit status, stdout, stderr)."""
    full = {**os.environ, "PYTHONPATH": str(ROOT), "DFLOOP_PROGRESS": "0", **(env or {})}
    p = subprocess.run([sys.executable, "-m", "dfloop.cli", *args], capture_output=True, text=True, env=full,
                       stdin=stdin, timeout=120)
    return p.returncode, p.stdout, p.stderr


def one_line_error(err: str, *fragments: str) -> None:
    assert "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dfloop: "), err
    for fragment in fragments:
        assert fragment in lines[0], (fragment, err)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A cache directory with 3 tables of the current code version and 2 of an old one, and a foreign file."""
    import dfloop.tables.cache as c

    directory = tmp_path / "cache"
    monkeypatch.setenv("DFLOOP_CACHE_DIR", str(directory))
    files = [c.save_table(directory / f"cur{i}.npz", {"x": np.arange(10.0 * (i + 1))}, f"k{i}", {}, {}) for i in range(3)]
    with monkeypatch.context() as m:
        m.setattr(c, "code_version", lambda: "0.0.1+old")
        files += [c.save_table(directory / f"old{i}.npz", {"x": np.arange(5.0)}, f"o{i}", {}, {}) for i in range(2)]
    (directory / "notes.txt").write_text("not dfloop's")
    return directory, files


# ------------------------------------------------------------------------------------------------ run --out
def test_out_that_is_a_regular_file_is_refused_before_any_work(tmp_path):
    target = tmp_path / "results"
    target.write_text("keep me")
    code, out, err = run_cli("run", "relay_hysteresis", "--out", str(target))
    assert code == 2 and out == ""
    one_line_error(err, f"--out {target}", "not a directory")
    assert target.read_text() == "keep me"


def test_out_that_cannot_be_created_is_refused(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    code, out, err = run_cli("run", "relay_hysteresis", "--out", str(blocker / "sub"))
    assert code == 2
    one_line_error(err, f"--out {blocker / 'sub'}", "cannot write there", "Not a directory")
    assert blocker.is_file()


def test_out_that_cannot_be_written_is_refused(tmp_path, monkeypatch, capsys):
    """A directory that exists but refuses files (read-only): the write check fails with EACCES."""
    import tempfile

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "TemporaryFile", refuse)
    assert main(["run", "relay_hysteresis", "--out", str(tmp_path)]) == 2
    one_line_error(capsys.readouterr().err, f"--out {tmp_path}", "Permission denied")
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------------------------------ cache dir
@pytest.mark.parametrize("value", ["", "  "])
def test_empty_cache_dir_variable_is_refused(value, tmp_path, monkeypatch):
    for args in (["cache", "info"], ["cache", "clear", "--yes"], ["run", "relay_hysteresis", "--out", str(tmp_path)]):
        code, out, err = run_cli(*args, env={"DFLOOP_CACHE_DIR": value})
        assert code == 2, (args, err)
        one_line_error(err, "DFLOOP_CACHE_DIR is set but empty", "unset it for the default")
    assert list(tmp_path.iterdir()) == []  # the run did not start
    monkeypatch.setenv("DFLOOP_CACHE_DIR", value)
    from dfloop.cache_admin import cache_info, clear_cache

    for call in (cache_info, clear_cache):
        with pytest.raises(ValueError, match="DFLOOP_CACHE_DIR is set but empty"):
            call()


# ------------------------------------------------------------------------------------------------ cache clear
def test_clear_lists_every_file_and_refuses_without_a_terminal(cache):
    directory, files = cache
    code, out, err = run_cli("cache", "clear", env={"DFLOOP_CACHE_DIR": str(directory)})
    assert code == 2
    one_line_error(err, "refused to remove these 5 files without confirmation", "stdin is not a terminal", "--yes")
    assert f"{len(files)} files" in out.splitlines()[0] and str(directory) in out.splitlines()[0]
    for f in files:
        assert f.name in out
    assert "notes.txt" not in out
    assert all(f.exists() for f in files)  # nothing removed


def test_clear_with_yes_removes_the_listed_files_only(cache):
    directory, files = cache
    code, out, err = run_cli("cache", "clear", "--yes", env={"DFLOOP_CACHE_DIR": str(directory)})
    assert code == 0 and err == ""
    assert "removed 5 files" in out
    assert not any(f.exists() for f in files) and (directory / "notes.txt").exists()


def test_clear_asks_on_a_terminal_and_respects_the_answer(cache, monkeypatch, capsys):
    directory, files = cache

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setattr(sys, "stdin", Terminal("n\n"))
    assert main(["cache", "clear", "--stale"]) == 1
    captured = capsys.readouterr()
    assert "2 stale files" in captured.out and "old0.npz" in captured.out and "cur0.npz" not in captured.out
    assert "Remove these 2 files? [y/N]" in captured.out and "nothing removed" in captured.err
    assert all(f.exists() for f in files)
    monkeypatch.setattr(sys, "stdin", Terminal("y\n"))
    assert main(["cache", "clear", "--stale"]) == 0
    assert "removed 2 stale files" in capsys.readouterr().out
    assert [f.exists() for f in files] == [True, True, True, False, False]


def test_clear_removes_exactly_the_files_it_listed(cache):
    """A table written between the listing and the confirmation is not removed unseen."""
    from dfloop.cache_admin import clear_cache

    directory, files = cache
    listed = clear_cache(dry_run=True)
    assert sorted(f.path for f in listed) == sorted(files) and all(f.exists() for f in files)
    late = directory / "late.npz"
    late.write_bytes(files[0].read_bytes())
    removed = clear_cache(files=listed)
    assert sorted(f.path for f in removed) == sorted(files)
    assert late.exists() and not any(f.exists() for f in files)


def test_clear_on_a_read_only_cache_reports_one_line(cache, monkeypatch, capsys):
    directory, files = cache
    real_unlink = Path.unlink

    def read_only(self, missing_ok=False):
        if self.parent == directory and self.name.startswith("old"):
            raise PermissionError(13, "Permission denied", str(self))
        return real_unlink(self, missing_ok=missing_ok)

    monkeypatch.setattr(Path, "unlink", read_only)
    assert main(["cache", "clear", "--yes"]) == 2
    captured = capsys.readouterr()
    one_line_error(captured.err, "could not remove 2 of 5 files", "old0.npz", "Permission denied")
    assert "removed 3 files" in captured.out
    assert [f.exists() for f in files] == [False, False, False, True, True]
    from dfloop.cache_admin import clear_cache

    with pytest.raises(PermissionError, match="could not remove 2 of 2 cache files"):
        clear_cache()


def test_cache_directory_that_cannot_be_listed(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("DFLOOP_CACHE_DIR", str(tmp_path))

    def unreadable(self, pattern):
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "glob", unreadable)
    assert main(["cache", "info"]) == 2
    one_line_error(capsys.readouterr().err, "cache info", "Permission denied")


def test_usage_errors_are_one_line(capsys):
    assert main(["cache", "frob"]) == 2
    one_line_error(capsys.readouterr().err, "invalid choice: 'frob'", "dfloop cache --help")
    assert main(["run"]) == 2
    one_line_error(capsys.readouterr().err, "the following arguments are required: scenes")
