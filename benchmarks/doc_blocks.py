"""Benchmark tables in the docs are written by the benchmarks, never copied by hand: each lives between two
markers that name the benchmark writing it, and a benchmark checks its markers before its long work starts."""

import json
import re
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]


def markers(name: str, writer: str) -> tuple:
    return f"<!-- {name}: written by {writer} -->", f"<!-- {name} end -->"


def check_block(path: Path, name: str, writer: str) -> None:
    """Exit with one line unless `path` holds the block's two markers (call before the long work)."""
    begin, end = markers(name, writer)
    text = path.read_text() if path.is_file() else ""
    if begin not in text or end not in text:
        raise SystemExit(f"{path}: no '{begin}' ... '{end}' markers to write the {name} between")


def read_block(path: Path, name: str, writer: str) -> str:
    """The text between the block's markers."""
    begin, end = markers(name, writer)
    text = path.read_text()
    return text[text.index(begin) + len(begin) : text.index(end)].strip("\n")


def write_block(path: Path, name: str, writer: str, body: str) -> None:
    """Replace the text between the block's markers with `body`."""
    check_block(path, name, writer)
    begin, end = markers(name, writer)
    block = f"{begin}\n{body.strip()}\n{end}"
    path.write_text(re.sub(re.escape(begin) + ".*?" + re.escape(end), lambda _: block, path.read_text(), flags=re.S))


# A benchmark's measurements are kept in the repository (its campaigns and checkpoints are not: they can be made
# again): a grid that outlives a sitting resumes from a fresh clone.
ROWS = REPO_ROOT / "benchmarks" / "rows"


def rows_file(name: str) -> Path:
    """Where benchmark `name` keeps its rows."""
    return ROWS / f"{name}.jsonl"


def load_rows(path: Path) -> list:
    """The rows measured so far (none before the first run)."""
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()] if path.exists() else []


def append_row(path: Path, row: dict) -> None:
    """Stream one measured row to the record, as soon as it is measured."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("a") as f:
        f.write(json.dumps(row) + "\n")
