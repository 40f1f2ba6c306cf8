"""Benchmark reports: each suite owns one marked section of ``docs/benchmarks.md``."""
import os

from mjccd.files import write_text


def write_section(path, name, text):
    """Replace the section ``name`` of the markdown file at ``path`` (or append it), atomically."""
    start, end = f"<!-- bench {name}: begin -->", f"<!-- bench {name}: end -->"
    block = f"{start}\n{text.rstrip()}\n{end}\n"
    if os.path.exists(path):
        with open(path, encoding="utf-8") as fh:
            old = fh.read()
    else:
        old = "# Benchmarks\n"
    if start in old and end in old:
        new = old[:old.index(start)] + block + old[old.index(end) + len(end) + 1:]
    else:
        new = old.rstrip("\n") + "\n\n" + block
    write_text(path, new)
