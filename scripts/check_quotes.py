#!/usr/bin/python3
"""Checks the seed article's quotes against a copy of the article.

    scripts/check_quotes.py ARTICLE.txt

The project holds the article's words only as quotes: the claims index (claims/index.toml, the
`original` of each claim) and the experiments (claims/experiments/*.toml, the `quote` of each
part). Given a copy of the article, this checks that its SHA-256 is the one the index records and
that every quote is the article's text, verbatim ("……" marks a cut: each piece between cuts must be
in the article, in order). White space is not compared: the text as received breaks lines inside
sentences (where the original had inline code) and runs list items together, and the quotes lay
them out to be read. Exit 0 when all hold, 1 when one does not (each is listed), 2 on bad input.
"""
import hashlib
import pathlib
import sys
import tomllib

ROOT = pathlib.Path(__file__).resolve().parent.parent
CUT = "……"


def squeeze(text):
    return "".join(text.split())


def pieces(quote):
    return [squeeze(p) for p in quote.split(CUT) if squeeze(p)]


def check(article, quote):
    """The pieces of the quote not found in the article, in order."""
    missing, at = [], 0
    for piece in pieces(quote):
        found = article.find(piece, at)
        if found < 0:
            missing.append(piece)
        else:
            at = found + len(piece)
    return missing


def main(argv):
    if len(argv) != 2:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    try:
        data = pathlib.Path(argv[1]).read_bytes()
    except OSError as e:
        print(f"check_quotes: {argv[1]}: {e.strerror}", file=sys.stderr)
        return 2
    article = squeeze(data.decode("utf-8"))
    index = tomllib.loads((ROOT / "claims" / "index.toml").read_text(encoding="utf-8"))
    failures = []
    digest = hashlib.sha256(data).hexdigest()
    if digest != index["source"]["sha256"]:
        failures.append(f"the article's SHA-256 is {digest}, the index records {index['source']['sha256']}")
    quotes = [(f"claims/index.toml: {c['id']}", c["original"]) for c in index["claim"]]
    for f in sorted((ROOT / "claims" / "experiments").glob("*.toml")):
        experiment = tomllib.loads(f.read_text(encoding="utf-8"))
        for k, part in enumerate(experiment.get("part", []), 1):
            quotes.append((f"claims/experiments/{f.name}: part {experiment['id']}.{k}", part.get("quote", "")))
    for where, quote in quotes:
        for piece in check(article, quote):
            failures.append(f"{where}: not in the article: {piece[:60]}{'...' if len(piece) > 60 else ''}")
    for f in failures:
        print(f)
    print(f"{len(quotes)} quotes, {len(failures)} problems")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
