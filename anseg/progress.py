"""Progress bars, made one way so that ``TQDM_DISABLE=1`` silences every one of them.

tqdm takes ``TQDM_*`` environment variables as the defaults of the arguments a call leaves out,
so a call that passes ``disable=False`` shows its bar whatever the environment says. The notebook
runner (:mod:`anseg.study.reproduce`) sets ``TQDM_DISABLE=1`` because an executed notebook is
read, not watched, and a bar left in its outputs is noise. So a bar here passes ``disable`` only
to hide itself.
"""

from __future__ import annotations

from tqdm.auto import tqdm


def progress(iterable=None, *, show: bool | None = True, **kwargs) -> tqdm:
    """A tqdm bar over ``iterable`` (or for ``total=`` steps), with tqdm's keyword arguments.

    ``show=False`` hides it; ``show=None`` shows it only where stderr is a terminal (tqdm's own
    ``disable=None``); ``show=True`` shows it unless ``TQDM_DISABLE`` is set.
    """
    if show is not True:
        kwargs["disable"] = None if show is None else True
    return tqdm(iterable, **kwargs)
