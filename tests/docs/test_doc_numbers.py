"""The user guide quotes the benchmark's numbers only as the benchmark last wrote them.

``make bench`` writes its JSON and, from it, ``docs/benchmarks.md`` and ``docs/wrap-solvers.md``. A paragraph
(or table) of the guide that cites the benchmark (``benchmarks/``, ``make bench``, "the benchmark") and quotes
numbers carries the marker ``<!-- docs-numbers: FILE -->`` on the line before it, FILE one of those two, and
every number it quotes with a decimal point or a thousands separator (0.216, 1.15, 13,380; plain counts such
as "24 anchors" are not checked) must appear in FILE. A number the benchmark does not write goes from the
guide. Nothing here runs the benchmark: it reads its committed output.
"""

import re

from helpers import REPOSITORY

GUIDE = REPOSITORY / "docs" / "user-guide.md"
SOURCES = {"benchmarks.md", "wrap-solvers.md"}
MARKER = re.compile(r"^<!-- docs-numbers: (?P<file>[\w.-]+) -->$")
CITES_BENCHMARK = re.compile(r"benchmarks/|make bench|the benchmark|benchmark's")
NUMBER = re.compile(r"(?<![\w.,])(?:\d{1,3}(?:,\d{3})+(?:\.\d+)?|\d+\.\d+(?:e-?\d+)?)(?![\w])")


def paragraphs(text: str) -> list[tuple[int, str | None, str]]:
    """(first line, marker file or None, text) of each paragraph outside fenced blocks (lines up to a blank line;
    each list item on its own), the marker taken from a marker line that opens the paragraph."""
    found, lines, start, fenced = [], [], 0, False
    for number, line in enumerate(text.splitlines() + [""], 1):
        if line.strip().startswith("```"):
            fenced = not fenced
            continue
        if fenced:
            continue
        item = re.match(r"^(?:[-*]|\d+\.) ", line) is not None  # a list item is a paragraph of its own
        if line.strip() and not (item and lines and not MARKER.match(lines[-1].strip())):
            if not lines:
                start = number
            lines.append(line)
            continue
        if line.strip():  # a list item after other lines: close them, open it
            marker = MARKER.match(lines[0].strip())
            found.append((start, marker["file"] if marker else None, "\n".join(lines[1:] if marker else lines)))
            lines, start = [line], number
            continue
        if lines:
            marker = MARKER.match(lines[0].strip())
            body = "\n".join(lines[1:] if marker else lines)
            found.append((start, marker["file"] if marker else None, body))
            lines = []
    return found


def quoted(body: str) -> list[str]:
    """The decimal and thousands-separated numbers of ``body`` (code spans and links left out)."""
    body = re.sub(r"`[^`]*`|\]\([^)]*\)|<!--.*?-->", " ", body, flags=re.DOTALL)
    return NUMBER.findall(body)


def written(number: str, source: str) -> bool:
    """``number`` is in ``source`` as a whole number (with or without its thousands separators)."""
    for form in {number, number.replace(",", "")}:
        if re.search(rf"(?<![\w.]){re.escape(form)}(?![\d])", source):
            return True
    return False


def test_numbers_from_the_benchmark_are_the_benchmarks():
    text = GUIDE.read_text(encoding="utf-8")
    problems, marked = [], 0
    for line, source_name, body in paragraphs(text):
        numbers = quoted(body)
        if source_name is None:
            if numbers and CITES_BENCHMARK.search(body) and not body.lstrip().startswith("<!--"):
                problems.append(f"user-guide.md:{line}: cites the benchmark and quotes {numbers[:4]}: mark it")
            continue
        marked += 1
        assert source_name in SOURCES, f"user-guide.md:{line}: docs-numbers names {source_name}"
        source = (REPOSITORY / "docs" / source_name).read_text(encoding="utf-8")
        missing = [number for number in numbers if not written(number, source)]
        if missing:
            problems.append(f"user-guide.md:{line}: not in {source_name}: {missing}")
    assert problems == []
    assert marked >= 3


def test_the_check_finds_a_number_the_benchmark_did_not_write():
    source = "| heavy | 0.216 | 13380 | 1.15 |"
    assert written("0.216", source) and written("13,380", source)
    assert not written("0.21", source) and not written("1.1", source)
    assert quoted("mean 0.028 % to 0.015 %, 13,380 vertices, `0.5` in code, 24 anchors") == ["0.028", "0.015", "13,380"]
