"""Progress bars: shown by default, hidden on request, and every one silenced by ``TQDM_DISABLE``.

tqdm reads ``TQDM_*`` when it is imported, so each case runs in a fresh process with the
environment it names (setting the variable in this process would change nothing).
"""

import os
import subprocess
import sys


def disabled(expressions: str, tqdm_disable: bool) -> tuple[list[str], str]:
    """The ``disable`` flag of each bar ``expressions`` builds in a fresh process, and what it wrote to stderr."""
    env = {k: v for k, v in os.environ.items() if k != "TQDM_DISABLE"} | ({"TQDM_DISABLE": "1"} if tqdm_disable else {})
    code = ("import io; from anseg.progress import progress; from anseg.datasets.common import progress_bar; "
            f"print(*[bar.disable for bar in ({expressions})])")
    run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return run.stdout.split(), run.stderr


def test_a_bar_shows_unless_told_otherwise():
    bars = ("progress(range(3), file=io.StringIO()), progress(range(3), show=False, file=io.StringIO()), "
            "progress_bar(list(range(50)), 'PSB Hand test', enabled=True)")
    assert disabled(bars, tqdm_disable=False)[0] == ["False", "True", "False"]


def test_tqdm_disable_silences_a_bar_that_would_show():
    """The notebook runner sets it for its kernels, so that no executed notebook keeps a bar in its outputs."""
    bars = "progress(range(3)), progress_bar(list(range(50)), 'PSB Hand test')"  # the second once ignored it
    assert disabled(bars, tqdm_disable=True) == (["True", "True"], "")


def test_show_none_leaves_it_to_whether_stderr_is_a_terminal():
    assert disabled("progress(range(3), show=None, file=io.StringIO()),", tqdm_disable=False)[0] == ["True"]
