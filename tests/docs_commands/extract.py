"""The documents' fenced blocks, the commands of the command blocks, and the keys that name them in COMMANDS."""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
COMMAND_LANGUAGES = {"sh", "python"}
DATA_LANGUAGES = {"text", "json", "ini"}


@dataclass(frozen=True)
class Block:
    document: str
    line: int
    language: str
    body: str

    def __str__(self) -> str:
        return f"{self.document}:{self.line} ({self.language or 'no language'})"


FENCE = re.compile(
    r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})(?P<info>[^\n`]*)\n(?P<body>.*?)^(?P=indent)(?P=fence)[ \t]*$",
    re.M | re.S,
)


@cache
def blocks() -> tuple[Block, ...]:
    found = []
    for path in DOCUMENTS:
        text = path.read_text()
        for match in FENCE.finditer(text):
            indent = match["indent"]
            body = "".join(line.removeprefix(indent) for line in match["body"].splitlines(keepends=True))
            language = match["info"].strip().split(" ")[0]
            line = text.count("\n", 0, match.start()) + 1
            found.append(Block(str(path.relative_to(ROOT)), line, language, body))
    return tuple(found)


def command_blocks() -> dict[str, list[Block]]:
    """The distinct bodies of the command blocks, each with the places it is written."""
    bodies: dict[str, list[Block]] = {}
    for block in blocks():
        if block.language in COMMAND_LANGUAGES:
            bodies.setdefault(block.body, []).append(block)
    return bodies


def commands(body: str, language: str) -> list[str]:
    """A python block is one command; a shell block's are its top-level commands (continued lines, quotes spanning
    lines and here-documents joined; comment lines between them dropped)."""
    if language == "python":
        return [body]
    found: list[str] = []
    current: list[str] = []
    heredoc: str | None = None
    for line in body.splitlines():
        if heredoc is not None:
            current.append(line)
            if line.strip() == heredoc:
                found.append("\n".join(current))
                current, heredoc = [], None
            continue
        if not current and (not line.strip() or line.lstrip().startswith("#")):
            continue
        current.append(line)
        if marker := re.search(r"<<-?\s*(['\"]?)(\w+)\1", line):
            heredoc = marker[2]
        elif not line.endswith("\\") and _quotes_closed("\n".join(current)):
            found.append("\n".join(current))
            current = []
    assert not current, f"an unfinished command: {current}"
    return found


def _quotes_closed(text: str) -> bool:
    try:
        shlex.split(text, comments=True)
    except ValueError:
        return False
    return True


def uncommented(command: str) -> str:
    """The command without its comments (a ``#`` that starts a word outside quotes, to the end of its line)."""
    kept, quote, comment, previous = [], "", False, "\n"
    for char in command:
        if comment and char == "\n":
            comment = False
        elif not comment and quote and char == quote:
            quote = ""
        elif not comment and not quote and char in "'\"":
            quote = char
        elif not comment and not quote and char == "#" and previous.isspace():
            comment = True
        if not comment:
            kept.append(char)
        previous = char
    return "\n".join(line.rstrip() for line in "".join(kept).splitlines())


def key(command: str) -> str:
    """What names a command in COMMANDS: its first line without its comment."""
    return uncommented(command).splitlines()[0].removesuffix("\\").strip()


def language(body: str) -> str:
    """The language of a command block's body."""
    return command_blocks()[body][0].language
