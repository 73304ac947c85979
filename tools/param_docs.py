#!/usr/bin/env python3
"""Write the parameter tables of docs/*.md from the parameter descriptions (issue 23 item 5).

    tools/param_docs.py build/apps/eco            # rewrite the generated blocks in docs/
    tools/param_docs.py --check build/apps/eco    # exit 1 and show the difference if a block is stale

A generated block in a docs page is

    <!-- generated: eco config describe --markdown canopy (tools/param_docs.py; do not edit) -->
    | key | default | ... |
    <!-- end generated -->

and holds exactly what `eco config describe --markdown canopy` prints (the descriptors of
core/param_desc.h: key, default, unit, meaning, allowed values, the flags declared from them). Edit the
descriptor (its one-line doc, range or default), rebuild eco, run this script. The C++ test
"docs parameter tables are the descriptors' output" (tests/docs_cli_test.cpp) makes the
same comparison, so the docs cannot drift from the code.
"""

import difflib
import os
import re
import subprocess
import sys

BEGIN = re.compile(r"^<!-- generated: eco (config describe [^(]*?) \(tools/param_docs\.py; do not edit\) -->$")
END = "<!-- end generated -->"


def render(eco, args):
    return subprocess.run([eco] + args.split(), check=True, capture_output=True, text=True).stdout


def update(text, eco, path):
    """The page with every generated block rewritten; ValueError for an unclosed block."""
    lines, out, i = text.split("\n"), [], 0
    while i < len(lines):
        out.append(lines[i])
        m = BEGIN.match(lines[i])
        i += 1
        if not m:
            continue
        end = i
        while end < len(lines) and lines[end] != END:
            end += 1
        if end == len(lines):
            raise ValueError(f"{path}: block '{m.group(1)}' has no '{END}' line")
        out.extend(render(eco, m.group(1)).rstrip("\n").split("\n"))
        i = end
    return "\n".join(out)


def main(argv):
    check = "--check" in argv
    args = [a for a in argv if a != "--check"]
    if len(args) not in (1, 2):
        sys.exit(__doc__)
    eco = args[0]
    docs = args[1] if len(args) == 2 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs")
    stale = 0
    for name in sorted(os.listdir(docs)):
        if not name.endswith(".md"):
            continue
        path = os.path.join(docs, name)
        with open(path) as f:
            text = f.read()
        new = update(text, eco, path)
        if new == text:
            continue
        if check:
            stale += 1
            sys.stdout.writelines(difflib.unified_diff(text.splitlines(True), new.splitlines(True), path, path + " (generated)"))
        else:
            with open(path, "w") as f:
                f.write(new)
            print(f"updated {path}")
    if stale:
        print(f"{stale} page(s) differ from the descriptors: run tools/param_docs.py {eco}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
