"""sphinx-gallery hooks for blobflow's examples: the pictures an example writes are its figures.

Every example writes its picture(s) as PNG files into ``$BLOBFLOW_EXAMPLES_OUT/NAME/`` (``NAME``
its file name without ``.py``), whatever draws them (a PyVista plotter, blobflow's own renderer),
and ``tests/test_examples.py`` checks that they are written.  :func:`reset` empties that folder
before the example runs; :func:`scraper` puts every PNG written there since into the gallery,
after the code block that wrote it.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

_reported: set[Path] = set()


def _folder(src_file) -> Path:
    return Path(os.environ["BLOBFLOW_EXAMPLES_OUT"]) / Path(src_file).stem


def reset(gallery_conf, fname, when) -> None:
    """Before each example (``when == "before"``): remove its outputs of an earlier build."""
    if when != "before":
        return
    shutil.rmtree(_folder(fname), ignore_errors=True)
    _reported.clear()


def scraper(block, block_vars, gallery_conf) -> str:
    """The reST of the pictures the code block wrote (copied into the gallery's images)."""
    from sphinx_gallery.scrapers import figure_rst

    folder = _folder(block_vars["src_file"])
    pictures = sorted((p for p in folder.glob("*.png") if p not in _reported),
                      key=lambda p: (p.stat().st_mtime, p.name)) if folder.is_dir() else []
    paths = []
    for picture in pictures:
        target = Path(next(block_vars["image_path_iterator"]))
        shutil.copyfile(picture, target)
        _reported.add(picture)
        paths.append(target)
    return figure_rst(paths, gallery_conf["src_dir"]) if paths else ""
