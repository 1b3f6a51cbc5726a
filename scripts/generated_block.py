"""A generated block in a hand-written page: the text between a BEGIN and an END marker line,
which a script (readme_tables.py, perf_report.py) owns and rewrites. Standard library only."""
import sys


def split(text, path, begin, end, prog):
    """(before, block, after) of a page's text, the block with its marker lines. Exits 2, naming
    the page and the markers, when they are missing."""
    b = text.find(begin)
    e = text.find(end)
    if b < 0 or e < 0 or e < b:
        print(f"{prog}: {path}: the markers of the generated block are missing "
              f"(a line {begin!r}, then a line {end!r})", file=sys.stderr)
        sys.exit(2)
    e += len(end)
    if e < len(text) and text[e] == "\n":
        e += 1
    return text[:b], text[b:e], text[e:]
