"""Report blocks in markdown documents: the lines between ``<!-- xted bench report OPTIONS -->`` and
``<!-- end of the report -->`` are what ``xted bench report OPTIONS`` prints, so a document that shows
the bench's table (BENCHMARKS.md, a paper draft) is brought up to the store by ``xted bench refresh``."""

from __future__ import annotations

import dataclasses
import shlex
from collections.abc import Callable

from xted.errors import InputError

BLOCK_START = "<!-- xted bench report"
BLOCK_END = "<!-- end of the report -->"
REFUSED_OPTIONS = ("--json", "--png", "--help")  # they print no markdown table, or draw a file beside it


@dataclasses.dataclass(frozen=True)
class ReportBlock:
    line: int  # 1-based line of the opening marker
    options: tuple[str, ...]  # the options of ``xted bench report``
    start: int  # index (in the document's lines) of the first line of the block's body
    end: int  # index of the closing marker


def report_blocks(text: str, name: str) -> list[ReportBlock]:
    """The report blocks of a document; an unclosed block, a nested opening marker or options that
    print no table are an InputError naming ``name`` and the line."""
    lines = text.splitlines()
    blocks, opened = [], None
    for index, line in enumerate(lines):
        stripped = line.strip()
        if stripped.startswith(BLOCK_START):
            if opened is not None:
                raise InputError(f"{name}:{opened[0] + 1}: report block not closed by {BLOCK_END!r} before the next one")
            opened = (index, _options(stripped, f"{name}:{index + 1}"))
        elif stripped == BLOCK_END and opened is not None:
            blocks.append(ReportBlock(line=opened[0] + 1, options=opened[1], start=opened[0] + 1, end=index))
            opened = None
    if opened is not None:
        raise InputError(f"{name}:{opened[0] + 1}: report block not closed by {BLOCK_END!r}")
    return blocks


def _options(marker: str, where: str) -> tuple[str, ...]:
    if not marker.endswith("-->"):
        raise InputError(f"{where}: the report marker must end on its line with '-->': {marker!r}")
    try:
        options = tuple(shlex.split(marker[len(BLOCK_START):-len("-->")]))
    except ValueError as err:
        raise InputError(f"{where}: the report marker's options do not parse: {err}") from None
    refused = [option for option in options if option.split("=")[0] in REFUSED_OPTIONS]
    if refused:
        raise InputError(f"{where}: {', '.join(refused)} in a report block: a block holds the markdown table only")
    return options


def refreshed(text: str, name: str, render: Callable[[tuple[str, ...]], str]) -> tuple[str, int]:
    """``text`` with the body of every report block replaced by ``render(options)``, and the number
    of blocks; an error of ``render`` (an InputError) is raised naming the block's line."""
    blocks = report_blocks(text, name)
    if not blocks:
        raise InputError(f"{name}: no report block (a line {BLOCK_START} OPTIONS --> and, below it, {BLOCK_END})")
    lines = text.splitlines()
    pieces, done = [], 0
    for block in blocks:
        try:
            body = render(block.options).rstrip("\n")
        except InputError as err:
            raise InputError(f"{name}:{block.line}: the report block's options: {err}") from None
        pieces += [*lines[done:block.start], *body.splitlines()]
        done = block.end
    pieces += lines[done:]
    return "\n".join(pieces) + ("\n" if text.endswith("\n") else ""), len(blocks)
