#!/usr/bin/env python3
"""Checks the links between the project's Markdown files (docs stay true).

    md_links.py SRCDIR

Every relative link [text](path#anchor) in a tracked-style .md file under
SRCDIR (build folders and hidden folders left out; links leaving SRCDIR
are not checked) must name a file that exists and, for a .md file, a
heading that the link's anchor names the way GitHub derives anchors (lower case, punctuation dropped,
spaces to hyphens, -1, -2 for repeats). Exit 1 with one line per broken
link, else 0.
"""
import os
import re
import sys


def slug(heading):
    s = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return s.replace(" ", "-")


def anchors(path):
    found, seen, fenced = set(), {}, False
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.startswith("```"):
                fenced = not fenced
                continue
            m = None if fenced else re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
            if m:
                s = slug(m.group(1))
                seen[s] = seen.get(s, -1) + 1
                found.add(s if seen[s] == 0 else f"{s}-{seen[s]}")
    return found


def main():
    root = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else ".")
    outside = os.path.dirname(root)
    files = []
    for d, dirs, names in os.walk(root):
        dirs[:] = sorted(x for x in dirs if not x.startswith((".", "build")))
        files += [os.path.join(d, n) for n in sorted(names) if n.endswith(".md")]
    bad, links, cache = 0, 0, {}
    for md in files:
        with open(md, encoding="utf-8") as f:
            text = f.read()
        text = re.sub(r"```.*?```", "", text, flags=re.S)  # code is not links
        text = re.sub(r"`[^`\n]*`", "", text)
        for m in re.finditer(r"\]\(([^)\s]+)\)", text):
            target = m.group(1)
            if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # http:, mailto:
                continue
            links += 1
            path, _, frag = target.partition("#")
            dest = os.path.normpath(os.path.join(os.path.dirname(md), path)) if path else md
            where = os.path.relpath(md, root)
            if not dest.startswith(root + os.sep):  # outside the tree: not this tree's
                continue
            if not os.path.exists(dest):
                print(f"{where}: no file {target}")
                bad += 1
            elif frag and dest.endswith(".md"):
                if dest not in cache:
                    cache[dest] = anchors(dest)
                if frag not in cache[dest]:
                    print(f"{where}: no heading for {target}")
                    bad += 1
    print(f"{len(files)} Markdown files, {links} relative links, {bad} broken")
    if links == 0:
        print("no links found: wrong SRCDIR?")
        return 1
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
