"""Run the worked examples of the documentation and check (or rewrite) the output they quote.

A page marks a file with ``<!-- example: NAME -->`` on the line before its fenced block, and a
command's output with ``<!-- output: COMMAND -->`` before the fenced block that quotes it.
``COMMAND`` is ``rodnet ...`` (the command line, run in a fresh folder holding the marked files)
or ``python NAME`` (a marked Python file, run there after the commands before it). Examples run
in the order of the page. In the quoted output, the wall time of ``done in X s wall`` is not
compared, and a first line ``$ ...`` (the prompt) is kept as written.

Usage: ``python docs/examples.py [--write] [PAGE.md ...]`` (default: every page of docs/);
without ``--write`` it reports the examples whose output differs, with ``--write`` it puts the
new output into the page. ``tests/test_docs_examples.py`` runs the check.
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

DOCS = Path(__file__).resolve().parent
MARK = re.compile(r"^<!-- (example|output): (.+?) -->\n```[a-z]*\n(.*?)^```\n", re.M | re.S)
WALL = re.compile(r"done in [0-9.]+ s wall")
QUIET = ["--quiet", "--set", "output.vtk=false", "--set", "output.picture=false",
         "--set", "output.plot=false"]
"""Added to every ``rodnet run`` and ``rodnet demo``: no progress line, no VTK or pictures
(they change no printed number)."""


@dataclass(frozen=True)
class Block:
    """A marked fenced block: ``kind`` "example" or "output", its ``label`` (file name or
    command), its text, and where the text starts and ends in the page."""

    kind: str
    label: str
    text: str
    start: int
    end: int


def blocks(page: str) -> list[Block]:
    """The marked blocks of a page, in order."""
    return [Block(m.group(1), m.group(2).strip(), m.group(3), m.start(3), m.end(3))
            for m in MARK.finditer(page)]


def _command(label: str, folder: Path) -> list[str]:
    words = shlex.split(label)
    if words[0] == "rodnet":
        extra = QUIET if len(words) > 1 and words[1] in ("run", "demo") else []
        return [sys.executable, "-m", "rodnet", *words[1:], *extra]
    if words[0] == "python":
        return [sys.executable, *words[1:]]
    raise ValueError(f"an output block must quote 'rodnet ...' or 'python FILE', not {label!r}")


def run_page(page: str, folder: Path) -> list[tuple[Block, str]]:
    """Run a page's examples in ``folder``; every output block with the output it gives now
    (the prompt line of the quoted block kept)."""
    results = []
    env = dict(os.environ, NUMBA_NUM_THREADS=os.environ.get("NUMBA_NUM_THREADS", "1"))
    for block in blocks(page):
        if block.kind == "example":
            (folder / block.label).write_text(block.text)
            continue
        done = subprocess.run(_command(block.label, folder), cwd=folder, env=env,
                              capture_output=True, text=True, timeout=1800)
        if done.returncode != 0:
            raise RuntimeError(f"{block.label} failed ({done.returncode}): {done.stderr[-1000:]}")
        prompt = block.text.splitlines(keepends=True)[0] if block.text.startswith("$ ") else ""
        results.append((block, prompt + done.stdout))
    return results


def same(quoted: str, got: str) -> bool:
    """Whether the quoted output is what the example gives now, wall times aside."""
    return WALL.sub("done in X s wall", quoted) == WALL.sub("done in X s wall", got)


def check(path: Path, write: bool = False) -> list[str]:
    """The labels of the output blocks of page ``path`` that differ from what their examples
    give now; with ``write``, the page is rewritten with the new output."""
    page = path.read_text()
    with tempfile.TemporaryDirectory(prefix="rodnet-docs-") as tmp:
        results = run_page(page, Path(tmp))
    stale = [(b, got) for b, got in results if not same(b.text, got)]
    if write and stale:
        for block, got in sorted(stale, key=lambda item: -item[0].start):
            page = page[:block.start] + got + page[block.end:]
        path.write_text(page)
    return [b.label for b, _ in stale]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("pages", nargs="*", type=Path)
    parser.add_argument("--write", action="store_true", help="put the new output into the pages")
    args = parser.parse_args()
    pages = args.pages or sorted(DOCS.glob("*.md"))
    for path in pages:
        if not blocks(path.read_text()):
            continue
        stale = check(path, args.write)
        state = "rewritten" if args.write and stale else ("stale" if stale else "up to date")
        print(f"{path}: {state}" + (f" ({', '.join(stale)})" if stale else ""))


if __name__ == "__main__":
    main()
