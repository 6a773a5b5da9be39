#!/usr/bin/env python3
"""Builds and runs the complete programs of docs/api.md with the commands
the page shows, and checks that they print what it quotes.

    python3 tests/tools/api_programs.py ROOT BUILD_DIR

A program is a ```c block holding `int main`. The block after it either
holds shell lines (`$ cc ... NAME.c ... && ./NAME`, then more `$` lines)
with the output of the last command under them, or, after the word
"prints", the output alone (then the program is built with the command of
"Building and linking"). `-Iinclude`, `build/` and `examples/` in the
commands are the source tree's and the build's; everything else is as
written, so a missing library on the documented line fails here.
Exit 1 with a diff for each program whose build fails or whose output
differs; 0 with a count when every one matches.
"""
import difflib
import os
import re
import subprocess
import sys
import tempfile


def blocks(text):
    """(language, body, text before the block) for each fenced block."""
    out, pos = [], 0
    for m in re.finditer(r"^```(\w*)\n(.*?)^```$", text, re.M | re.S):
        out.append((m.group(1), m.group(2), text[pos:m.start()]))
        pos = m.end()
    return out


def main():
    root, build = (os.path.abspath(p) for p in sys.argv[1:3])
    text = open(os.path.join(root, "docs", "api.md"), encoding="utf-8").read()
    generic = re.search(r"^(cc -std=c11 .*prog\.c build/libpsys\.a .*-o prog)$", text, re.M)
    if not generic:
        print("api_programs: no build line with prog.c in docs/api.md's Building and linking")
        return 1
    bs = blocks(text)
    failed, ran = 0, 0
    with tempfile.TemporaryDirectory(prefix="psys-api-") as tmp:
        for k, (lang, body, _) in enumerate(bs):
            if lang != "c" or "int main" not in body or k + 1 >= len(bs):
                continue
            _, shown, between = bs[k + 1]
            lines = shown.splitlines()
            if lines and lines[0].startswith("$ cc "):
                cmds = [line[2:] for line in lines if line.startswith("$ ")]
                expect = [line for line in lines if not line.startswith("$ ")]
                name = re.search(r"(\w+)\.c ", cmds[0]).group(1)
            elif between.strip().endswith("prints"):
                name = f"program{k}"
                cmds = [generic.group(1).replace("prog", name), f"./{name}"]
                expect = lines
            else:
                continue
            ran += 1
            with open(os.path.join(tmp, f"{name}.c"), "w", encoding="utf-8") as f:
                f.write(body)
            out = ""
            for cmd in cmds:
                cmd = (cmd.replace("-Iinclude", f"-I{root}/include").replace("build/", f"{build}/")
                       .replace("examples/", f"{root}/examples/"))
                p = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], cwd=tmp, capture_output=True, text=True)
                if p.returncode != 0 and "| head" not in cmd:
                    print(f"api_programs: {name}: `{cmd}` exited {p.returncode}:\n{p.stdout}{p.stderr}")
                    failed += 1
                    break
                out = p.stdout
            else:
                got = out.splitlines()
                if got != expect:
                    failed += 1
                    print(f"api_programs: {name}: output differs from docs/api.md:")
                    print("\n".join(difflib.unified_diff(expect, got, "docs/api.md", "program", lineterm="")))
    if ran == 0:
        print("api_programs: no programs found in docs/api.md")
        return 1
    print(f"api_programs: {ran} programs, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
