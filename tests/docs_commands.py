"""The shell commands of README.md and docs/*.md, taken from their ```sh blocks so that tests run them as written.

A command is a line of a ```sh block (with its `\\` and open-quote continuations) whose program is one the docs
teach (`plem`, `make`); `sudo ` and `.venv/bin/` are dropped, as are comments. A line of such a block that is not a
command is output the doc shows for the command above it. Every command is either run by
tests/e2e/test_docs_commands.py or listed in NOT_RUN with the reason it is not.
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass, field
from pathlib import Path

from plem.cli.app import COMMANDS

ROOT = Path(__file__).resolve().parents[1]
DOCS: tuple[Path, ...] = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))
PROGRAMS = ("plem", "make")
_FENCE = re.compile(r"^\s*```\s*(\S*)")
_NAMED_FILE = re.compile(r"^#\s*(\S+\.ya?ml)\s*$")

#: The commands of the docs that no test runs, each with why. A synopsis cannot run as written; an interface
#: like enp3s0 is a real arm's.
NOT_RUN: dict[str, str] = {
    "make run": "builds the venv and the core in place, then runs the launch the tests start themselves",
    "make test": "runs the test suite this test is part of",
    "plem doctor enp3s0": "a real arm's wired interface",
    "plem doctor enp3s0 --format json": "a real arm's wired interface",
    "plem ethercat scan enp3s0": "a real arm's wired interface",
    "plem launch eth_interface:=enp3s0 robot_serial:=PE07I7E0E001": "a real arm on a real interface",
    "plem state [--watch] [--format json] [--robot-id ID]": "a synopsis: [...] marks options",
    "plem move --to home|<pose>|q1,q2,... [--speed-scale 0.5] [--robot-id ID]": "a synopsis: a|b alternatives",
    "plem mode free_drive|hold|idle [--robot-id ID]": "a synopsis: a|b alternatives",
    "plem reset [--robot-id ID]": "a synopsis: [...] marks options",
    "plem create-description --name my_robot --dof 6 [--with-moveit] [--no-launch] [--force] [--output DIR]":
        "a synopsis: [...] marks options",
    "plem validate ./my_robot_description [--strict] [--format json]": "a synopsis: [...] marks options",
    "plem bag plot ~/bags/rt_monitoring --out run.png --from 10:15:40 --to 10:16:10":
        "the window is a time of the doc's own recording; `plem bag plot ... --out run.png` runs",
    "plem view --bag ~/bags/rt_monitoring --fault 1":
        "needs a recorded fault, which nothing outside a launched simulated arm can cause; "
        "tests/e2e/test_view_replay.py runs this command on bags of a drive fault",
}


@dataclass(frozen=True)
class DocCommand:
    """One command of a doc as a user types it."""

    doc: str                              #: the doc's path from the repository's root
    line: int                             #: the line the command starts on
    text: str                             #: one line: continuations joined, comment and prefixes dropped
    sudo: bool = False                    #: the doc runs it as root
    comment: str = ""                     #: the doc's comment on the command
    output: tuple[str, ...] = field(default=())  #: lines the doc shows the command printing

    @property
    def argv(self) -> list[str]:
        return shlex.split(self.text)

    def where(self) -> str:
        return f"{self.doc}:{self.line}: {self.text}"


def _split_comment(line: str) -> tuple[str, str]:
    """(code, comment) of a shell line: a `#` outside quotes, at the start of a word, begins the comment."""
    quote = ""
    for index, char in enumerate(line):
        if quote:
            quote = "" if char == quote else quote
        elif char in "'\"":
            quote = char
        elif char == "#" and (index == 0 or line[index - 1].isspace()):
            return line[:index].rstrip(), line[index + 1:].strip()
    return line.rstrip(), ""


def _complete(text: str) -> bool:
    """Whether a shell line is complete: no trailing backslash and no open quote."""
    if text.endswith("\\"):
        return False
    try:
        shlex.split(text)
    except ValueError:
        return False
    return True


def _is_command(text: str) -> bool:
    """A line runs a program the docs teach; for plem, one of its commands (else it is output shown)."""
    words = text.split()
    if not words or words[0] not in PROGRAMS:
        return False
    return words[0] != "plem" or len(words) == 1 or words[1].startswith("-") or words[1] in COMMANDS


def _unprefixed(text: str) -> tuple[str, bool]:
    sudo = text.startswith("sudo ")
    text = text.removeprefix("sudo ").lstrip()
    return text.removeprefix(".venv/bin/"), sudo


def _blocks(markdown: str, language: str) -> list[tuple[int, list[str]]]:
    """(first line number, lines) of every fenced block of `language`."""
    blocks: list[tuple[int, list[str]]] = []
    inside: str | None = None
    for number, line in enumerate(markdown.splitlines(), 1):
        fence = _FENCE.match(line)
        if fence and inside is None:
            inside = fence.group(1)
            if inside == language:
                blocks.append((number + 1, []))
        elif fence:
            inside = None
        elif inside == language:
            blocks[-1][1].append(line)
    return blocks


def commands_of(markdown: str, doc: str) -> list[DocCommand]:
    """The commands of the ```sh blocks of one markdown text, in order."""
    found: list[DocCommand] = []
    for first, lines in _blocks(markdown, "sh"):
        pending, start = "", 0
        for offset, raw in enumerate(lines):
            if pending:
                joined = pending.removesuffix("\\").rstrip() + " " + raw.strip()
            else:
                joined, start = raw.strip(), first + offset
            code, comment = _split_comment(joined)
            if not code:
                continue
            text, sudo = _unprefixed(code)
            if not pending and not _is_command(text):
                if not found or found[-1].line < first:
                    raise ValueError(f"{doc}:{start}: {joined!r} is neither a command nor the output of one")
                last = found.pop()
                found.append(DocCommand(last.doc, last.line, last.text, last.sudo, last.comment,
                                        (*last.output, joined)))
                continue
            if not _complete(code):
                pending = joined
                continue
            pending = ""
            found.append(DocCommand(doc, start, text, sudo, comment))
        if pending:
            raise ValueError(f"{doc}:{start}: {pending!r} does not end (a trailing \\ or an open quote)")
    return found


def doc_name(path: Path) -> str:
    return str(path.relative_to(ROOT))


def doc_commands(docs: tuple[Path, ...] = DOCS) -> list[DocCommand]:
    """Every command of the docs, README.md first, then docs/*.md by name, each in its doc's order."""
    return [command for path in docs for command in commands_of(path.read_text(), doc_name(path))]


def doc_files(path: Path) -> dict[str, str]:
    """The files a doc shows in full: ```yaml blocks whose first line is a comment naming the file (`# NAME.yaml`)."""
    files = {}
    for _, lines in _blocks(path.read_text(), "yaml"):
        named = _NAMED_FILE.match(lines[0]) if lines else None
        if named:
            files[named.group(1)] = "\n".join(lines) + "\n"
    return files


def synopsis(command: DocCommand) -> bool:
    """A usage line, not a command: optional parts in [...], alternatives a|b, placeholders <x>."""
    unquoted = re.sub(r"'[^']*'|\"[^\"]*\"", "", command.text)
    return any(mark in unquoted for mark in ("[", "|", "<"))
