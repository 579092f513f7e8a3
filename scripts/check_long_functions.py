#!/usr/bin/env python3
"""Fail when a Rust function of the libraries, the CLI or the Python bindings is longer
than 120 lines (from its `fn` line to its closing brace), tests and the per-ISA SIMD
kernels (files named after an instruction set: avx2.rs, avx512.rs, neon.rs, sse*.rs)
excepted. Comments, strings and character literals are blanked before the braces are
counted, so braces inside messages do not count."""
import glob
import re
import sys

LIMIT = 120
SIMD = re.compile(r"/(avx2|avx512|neon|sse\d*)\.rs$")
FN = re.compile(
    r'^\s*(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?(extern\s+"C"\s+)?fn\s+(\w+)'
)


def blank(src: str) -> str:
    """`src` with comments, strings and char literals replaced by empty ones (newlines kept)."""
    out, i, n = [], 0, len(src)
    while i < n:
        c = src[i]
        if src.startswith("//", i):
            j = src.find("\n", i)
            i = n if j < 0 else j
            continue
        if src.startswith("/*", i):
            depth = 0
            while i < n:
                if src.startswith("/*", i):
                    depth, i = depth + 1, i + 2
                elif src.startswith("*/", i):
                    depth, i = depth - 1, i + 2
                else:
                    if src[i] == "\n":
                        out.append("\n")
                    i += 1
                if depth == 0:
                    break
            continue
        raw = re.match(r'b?r(#*)"', src[i : i + 10])
        if raw and (i == 0 or not (src[i - 1].isalnum() or src[i - 1] == "_")):
            end = '"' + raw.group(1)
            j = src.find(end, i + raw.end())
            out.append('""' + "\n" * src[i:j].count("\n"))
            i = j + len(end)
            continue
        if c == '"':
            j = i + 1
            while src[j] != '"':
                j += 2 if src[j] == "\\" else 1
            out.append('""' + "\n" * src[i:j].count("\n"))
            i = j + 1
            continue
        if c == "'":
            ch = re.match(r"'(\\(x..|u\{[^}]*\}|.)|[^\\'])'", src[i : i + 12])
            if ch:
                out.append("''")
                i += ch.end()
                continue
        out.append(c)
        i += 1
    return "".join(out)


def long_functions(path: str):
    lines = blank(open(path, encoding="utf-8").read()).split("\n")
    for i, line in enumerate(lines):
        m = FN.match(line)
        if not m:
            continue
        depth, started, j = 0, False, i
        while j < len(lines):
            for c in lines[j]:
                if c == "{":
                    depth, started = depth + 1, True
                elif c == "}":
                    depth -= 1
            if started and depth == 0:
                break
            if not started and lines[j].rstrip().endswith(";"):
                break
            j += 1
        if started and j - i + 1 > LIMIT:
            yield j - i + 1, i + 1, m.group(7)


def main() -> int:
    files = sorted(
        glob.glob("crates/*/src/**/*.rs", recursive=True)
        + glob.glob("python/src/**/*.rs", recursive=True)
    )
    found = []
    for f in files:
        if "/tests/" in f or f.endswith("tests.rs") or SIMD.search(f):
            continue
        found += [(n, f, line, name) for n, line, name in long_functions(f)]
    for n, f, line, name in sorted(found, reverse=True):
        print(f"{f}:{line}: fn {name} is {n} lines (limit {LIMIT})")
    if found:
        return 1
    print(f"no function over {LIMIT} lines in {len(files)} files")
    return 0


if __name__ == "__main__":
    sys.exit(main())
