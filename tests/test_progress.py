"""Progress bars: shown by default, hidden on request, and every one silenced by ``TQDM_DISABLE``."""

import io
import os
import subprocess
import sys

from anseg.progress import progress


def test_a_bar_shows_unless_told_or_silenced(monkeypatch):
    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    assert not progress(range(3), file=io.StringIO()).disable
    assert progress(range(3), show=False, file=io.StringIO()).disable


def test_tqdm_disable_silences_a_bar_that_would_show():
    """The notebook runner sets it for its kernels, so that no executed notebook keeps a bar in its outputs.

    tqdm reads the variable when it is imported, hence a fresh process.
    """
    code = ("from anseg.progress import progress; from anseg.datasets.common import progress_bar; "
            "print(progress(range(3)).disable, progress_bar(list(range(50)), 'PSB Hand test').disable)")
    env = {**os.environ, "TQDM_DISABLE": "1"}
    run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert run.stdout.split() == ["True", "True"] and run.stderr == ""


def test_show_none_leaves_it_to_whether_stderr_is_a_terminal(monkeypatch):
    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    assert progress(range(3), show=None, file=io.StringIO()).disable  # a StringIO is no terminal
