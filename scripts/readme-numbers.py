#!/usr/bin/env python3
"""Rewrites every tagged number in README.md and docs/**/*.md from the committed output it names.

A tagged number is written `0.521<!-- plus_fcal2_nwire/fcal2_3nwires/summary.json#validation.pre3d_mm.mean -->`
(the key syntax: fields, `[3]` indices, `[field=value]` selectors, a trailing
`*1000` scale). The number keeps its decimals; a count (an integer in the
JSON) is written without any. `tests/readme_claims.rs` fails when
a tagged number differs from reports/; run this after regenerating reports/.

`--check` writes nothing: it exits 1 at the first tagged number that differs
from reports/, naming the page, line, number and key (exit 0 when none does).
`--root DIR` reads DIR's README.md, docs/ and reports/ instead of the checkout's.
"""
import json
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
if "--root" in sys.argv:
    ROOT = pathlib.Path(sys.argv[sys.argv.index("--root") + 1]).resolve()
CHECK = "--check" in sys.argv
TAG = re.compile(r"(-?[0-9]+(?:\.[0-9]+)?)<!-- ([^#> ]+\.json)#(.+?) -->")


def lookup(data, key):
    scale = 1.0
    if "*" in key:
        key, s = key.split("*", 1)
        scale = float(s)
    value = data
    for segment in key.split("."):
        name, _, selector = segment.partition("[")
        if name:
            value = value[name]
        if selector:
            selector = selector.rstrip("]")
            if "=" in selector:
                field, want = selector.split("=", 1)
                value = next(e for e in value if e.get(field) == want)
            else:
                value = value[int(selector)]
    if isinstance(value, int) and not isinstance(value, bool) and scale == 1.0:
        return value
    return float(value) * scale


def documents():
    """README.md and every Markdown page below docs/, in a fixed order."""
    return [ROOT / "README.md"] + sorted((ROOT / "docs").rglob("*.md"))


def main():
    cache = {}
    failed = []
    total = 0
    for page in documents():
        name = page.relative_to(ROOT)
        text = page.read_text()

        def fill(m):
            written, file, key = m.group(1), m.group(2), m.group(3)
            if file not in cache:
                cache[file] = json.loads((ROOT / "reports" / file).read_text())
            # A count (an integer in the JSON) is written as one.
            decimals = len(written.split(".")[1]) if "." in written else 0
            try:
                value = lookup(cache[file], key)
            except (KeyError, IndexError, StopIteration, TypeError, ValueError) as e:
                failed.append(f"{name}: reports/{file}#{key}: {type(e).__name__} {e}")
                return m.group(0)
            if isinstance(value, int):
                decimals = 0
            return f"{value:.{decimals}f}<!-- {file}#{key} -->"

        new, count = TAG.subn(fill, text)
        total += count
        if CHECK:
            for line_no, (old_line, new_line) in enumerate(zip(text.split("\n"), new.split("\n")), 1):
                if old_line != new_line:
                    for a, b in zip(TAG.finditer(old_line), TAG.finditer(new_line)):
                        if a.group(1) != b.group(1):
                            sys.exit(f"{name}:{line_no}: {a.group(1)} drifted: reports/{a.group(2)}#{a.group(3)} is {b.group(1)}")
            continue
        if new != text:
            page.write_text(new)
    verb = "match" if CHECK else "rewritten from"
    print(f"{total - len(failed)} of {total} tagged numbers {verb} reports/", file=sys.stderr)
    if failed:
        sys.exit("\n".join(failed))


if __name__ == "__main__":
    main()
