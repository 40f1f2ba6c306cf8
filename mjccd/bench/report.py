"""Benchmark reports: each suite owns one marked section of ``docs/benchmarks.md``."""
import os


def write_section(path, name, text):
    """Replace the section ``name`` of the markdown file at ``path`` (or append it)."""
    start, end = f"<!-- bench {name}: begin -->", f"<!-- bench {name}: end -->"
    block = f"{start}\n{text.rstrip()}\n{end}\n"
    old = open(path).read() if os.path.exists(path) else "# Benchmarks\n"
    if start in old and end in old:
        new = old[:old.index(start)] + block + old[old.index(end) + len(end) + 1:]
    else:
        new = old.rstrip("\n") + "\n\n" + block
    with open(path, "w") as fh:
        fh.write(new)
