#!/usr/bin/env python3
"""No module import cycles inside any crate of the workspace.

For every crate root (crates/*/src/lib.rs and main.rs, python/src/lib.rs) the script
builds the module tree from the `mod` declarations (files, `#[path]`, inline modules),
collects the paths each module refers to (`use` declarations and `crate::`/`super::`/
`self::` paths in the code; comments and string literals are ignored), resolves them to
the module that defines the item (following `use` re-exports), and draws an edge between
the two modules' branches below their nearest common ancestor: `a::x::f` using
`a::y::g` is the edge x -> y among the children of `a`. A module using its ancestors'
items, or its own submodules, is no edge (that is how Rust modules are nested).

A cycle is a set of sibling modules that reach each other through these edges. The
script prints every cycle with the references that close it (file:line) and exits 1.
Test code (`#[cfg(test)]` items and modules) is left out: it may use any module; with
--tests it is checked too.

Usage: scripts/check_cycles.py [--tests] [--known FILE] [CRATE_SRC_DIR ...]

--known FILE: the cycles listed in FILE (the first line of each report, one a line) are
printed but do not fail the check; a new cycle does (scripts/test.sh checks with no
known cycle: the workspace has none).
"""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


# --------------------------------------------------------------------------------------
# Lexing: comments and string/char literals become spaces (offsets and lines are kept).


def blank(src: str) -> str:
    out = list(src)
    i, n = 0, len(src)

    def wipe(a: int, b: int) -> None:
        for k in range(a, min(b, n)):
            if out[k] != "\n":
                out[k] = " "

    while i < n:
        c = src[i]
        if src.startswith("//", i):
            j = src.find("\n", i)
            j = n if j < 0 else j
            wipe(i, j)
            i = j
        elif src.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if src.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif src.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            wipe(i, j)
            i = j
        elif c == "r" and re.match(r'r#*"', src[i : i + 300]) and not _ident_before(src, i):
            m = re.match(r'r(#*)"', src[i:])
            end = src.find('"' + m.group(1), i + len(m.group(0)))
            end = n if end < 0 else end + 1 + len(m.group(1))
            wipe(i + len(m.group(0)), end - 1 - len(m.group(1)))
            i = end
        elif c == "b" and src.startswith('b"', i) and not _ident_before(src, i):
            i += 1
        elif c == '"':
            j = i + 1
            while j < n and src[j] != '"':
                j += 2 if src[j] == "\\" else 1
            wipe(i + 1, j)
            i = j + 1
        elif c == "'":
            # A char literal ('x', '\n', '\u{..}') or a lifetime ('a).
            m = re.match(r"'(\\(u\{[0-9a-fA-F]+\}|x[0-9a-fA-F]{2}|.)|[^\\'])'", src[i : i + 12])
            if m:
                wipe(i + 1, i + len(m.group(0)) - 1)
                i += len(m.group(0))
            else:
                i += 1
        else:
            i += 1
    return "".join(out)


def _ident_before(src: str, i: int) -> bool:
    return i > 0 and (src[i - 1].isalnum() or src[i - 1] == "_")


def matching_brace(text: str, i: int) -> int:
    """Index just past the brace that closes the one at text[i]."""
    depth = 0
    for j in range(i, len(text)):
        if text[j] == "{":
            depth += 1
        elif text[j] == "}":
            depth -= 1
            if depth == 0:
                return j + 1
    return len(text)


# --------------------------------------------------------------------------------------
# The module tree.


@dataclass
class Module:
    path: tuple[str, ...]
    file: Path
    text: str = ""  # blanked text of the file
    ranges: list[tuple[int, int]] = field(default_factory=list)  # own code (not children)
    children: dict[str, "Module"] = field(default_factory=dict)
    parent: "Module | None" = None
    uses: dict[str, list[tuple[str, ...]]] = field(default_factory=dict)  # name -> paths
    globs: list[tuple[str, ...]] = field(default_factory=list)
    items: set[str] = field(default_factory=set)
    refs: list[tuple[tuple[str, ...], int]] = field(default_factory=list)  # path, line

    def name(self) -> str:
        return "::".join(("crate",) + self.path)


ATTR = re.compile(r"#!?\[")
CFG_TEST = re.compile(r"#\[\s*cfg\s*\((?:[^\]]*\W)?test\b")
ITEM_KW = re.compile(
    r"\b(?:pub(?:\s*\([^)]*\))?\s+)?(?:unsafe\s+)?"
    r"(struct|enum|fn|trait|type|const|static|union|mod|macro_rules!)\s+(r#)?(\w+)"
)


class Crate:
    def __init__(self, root_file: Path, tests: bool):
        self.tests = tests
        self.errors: list[str] = []
        self.root = self.load(root_file, (), None, root_file.parent)

    def load(self, file: Path, path, parent, child_dir: Path) -> Module:
        raw = file.read_text(encoding="utf-8")
        mod = Module(path=path, file=file, parent=parent)
        mod.text = blank(raw)
        self.scan(mod, raw, 0, len(raw), child_dir)
        return mod

    def scan(self, mod: Module, raw: str, start: int, end: int, child_dir: Path) -> None:
        """Splits text[start:end] into this module's own code and its child modules."""
        text = mod.text
        own_from = start
        i = start
        pending_attrs: list[tuple[int, int]] = []
        while i < end:
            c = text[i]
            if c == "#" and ATTR.match(text, i):
                j = text.find("[", i)
                k = _matching_bracket(text, j)
                pending_attrs.append((i, k))
                i = k
                continue
            if c.isspace():
                i += 1
                continue
            m = re.compile(r"(?:pub(?:\s*\([^)]*\))?\s+)?mod\s+(r#)?(\w+)\s*([;{])").match(text, i)
            attrs = [raw[a:b] for a, b in pending_attrs]
            is_test = any(CFG_TEST.match(a) and "not(test" not in a.replace(" ", "") for a in attrs)
            item_start = pending_attrs[0][0] if pending_attrs else i
            if m and not _ident_before(text, i):
                name = m.group(2)
                if m.group(3) == ";":
                    item_end = m.end()
                else:
                    item_end = matching_brace(text, m.end() - 1)
                mod.ranges.append((own_from, item_start))
                own_from = item_end
                if is_test and not self.tests:
                    pass
                elif m.group(3) == ";":
                    file = self.child_file(mod, name, attrs, child_dir)
                    if file is None:
                        self.errors.append(f"{mod.file}: module `{name}`: file not found")
                    else:
                        sub_dir = file.parent / name if file.name != "mod.rs" else file.parent
                        if any("path" in a for a in attrs):
                            sub_dir = file.parent
                        child = self.load(file, mod.path + (name,), mod, sub_dir)
                        mod.children[name] = child
                else:
                    child = Module(path=mod.path + (name,), file=mod.file, parent=mod)
                    child.text = text
                    self.scan(child, raw, m.end(), item_end - 1, child_dir / name)
                    mod.children[name] = child
                pending_attrs = []
                i = item_end
                continue
            if is_test and not self.tests:
                # Skip the #[cfg(test)] item: up to its `;` or its closing brace.
                j = i
                while j < end and text[j] not in ";{":
                    j += 1
                item_end = j + 1 if j < end and text[j] == ";" else matching_brace(text, j)
                mod.ranges.append((own_from, item_start))
                own_from = item_end
                pending_attrs = []
                i = item_end
                continue
            pending_attrs = []
            # Skip the rest of the token.
            m2 = re.compile(r"\w+|.").match(text, i)
            i = m2.end()
        mod.ranges.append((own_from, end))

    def child_file(self, mod: Module, name: str, attrs: list[str], child_dir: Path):
        for a in attrs:
            m = re.search(r'path\s*=\s*"([^"]+)"', a)
            if m:
                return mod.file.parent / m.group(1)
        for cand in (child_dir / f"{name}.rs", child_dir / name / "mod.rs"):
            if cand.is_file():
                return cand
        return None

    def modules(self):
        stack = [self.root]
        while stack:
            m = stack.pop()
            yield m
            stack.extend(m.children.values())


def _matching_bracket(text: str, i: int) -> int:
    depth = 0
    for j in range(i, len(text)):
        if text[j] == "[":
            depth += 1
        elif text[j] == "]":
            depth -= 1
            if depth == 0:
                return j + 1
    return len(text)


# --------------------------------------------------------------------------------------
# Paths: `use` trees, inline crate::/super::/self:: paths, item definitions.

USE = re.compile(r"\b(pub(?:\s*\([^)]*\))?\s+)?use\s+([^;]*);")
INLINE = re.compile(r"(?<![\w$:])((?:crate|super|self)(?:\s*::\s*(?:super|\w+))+)")
VIS_IN = re.compile(r"pub\s*\(\s*in\s+[^)]*\)")


def expand_use_tree(tree: str) -> list[tuple[list[str], str | None]]:
    """`a::{b, c::d, f::*}` (no whitespace) -> [(['a','b'], 'b'), (['a','c','d'], 'd'),
    (['a','f','*'], None)]: each path with the name it brings into scope."""
    out: list[tuple[list[str], str | None]] = []

    def rec(prefix: list[str], s: str) -> None:
        if s.startswith("::"):
            s = s[2:]
        if not s:
            return
        if s.startswith("{") and s.endswith("}"):
            for part in split_top(s[1:-1]):
                rec(prefix, part)
            return
        i = s.find("::{")
        if i >= 0 and s.endswith("}"):
            rec(prefix + s[:i].split("::"), s[i + 2 :])
            return
        segs = prefix + s.split("::")
        if segs[-1] == "self":
            segs = segs[:-1]
        out.append((segs, None if segs[-1] == "*" else segs[-1]))

    rec([], tree)
    return out


def split_top(s: str) -> list[str]:
    parts, depth, cur = [], 0, ""
    for ch in s:
        if ch == "{":
            depth += 1
        elif ch == "}":
            depth -= 1
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    parts.append(cur)
    return [p for p in parts if p.strip()]


def parse_use(body: str) -> list[tuple[list[str], str | None]]:
    """The paths of a `use` declaration's tree, with `as` renames."""
    renames: dict[str, str] = {}

    def sub(m: re.Match) -> str:
        key = f"__AS{len(renames)}__"
        renames[key] = m.group(2)
        return m.group(1) + key

    body = re.sub(r"([\w*]+)\s+as\s+(\w+)", sub, body)
    body = re.sub(r"\s+", "", body)
    out = []
    for segs, name in expand_use_tree(body):
        m = re.match(r"^(.*?)(__AS\d+__)$", segs[-1])
        if m:
            segs = segs[:-1] + [m.group(1)]
            name = renames[m.group(2)]
            if name == "_":
                name = None
        out.append((segs, name))
    return out


def line_of(text: str, pos: int) -> int:
    return text.count("\n", 0, pos) + 1


def collect(crate: Crate) -> None:
    for mod in crate.modules():
        for a, b in mod.ranges:
            code = mod.text[a:b]
            code = VIS_IN.sub(lambda m: " " * len(m.group(0)), code)
            used_spans = []
            for m in USE.finditer(code):
                used_spans.append((m.start(), m.end()))
                line = line_of(mod.text, a + m.start())
                for segs, name in parse_use(m.group(2)):
                    if not segs or segs[0] in ("std", "core", "alloc"):
                        continue
                    if segs[-1] == "*":
                        mod.globs.append(tuple(segs[:-1]))
                        mod.refs.append((tuple(segs[:-1]), line))
                        continue
                    if name:
                        mod.uses.setdefault(name, []).append(tuple(segs))
                    mod.refs.append((tuple(segs), line))
            for m in INLINE.finditer(code):
                if any(s <= m.start() < e for s, e in used_spans):
                    continue
                segs = re.sub(r"\s+", "", m.group(1)).split("::")
                mod.refs.append((tuple(segs), line_of(mod.text, a + m.start())))
            for m in ITEM_KW.finditer(code):
                mod.items.add(m.group(3))


# --------------------------------------------------------------------------------------
# Resolution and cycles.


def resolve(crate: Crate, mod: Module, segs: tuple[str, ...], seen=None):
    """The module that defines the item `segs` names, seen from `mod` (None: outside)."""
    seen = set() if seen is None else seen
    key = (mod.path, segs)
    if key in seen:
        return None
    seen.add(key)
    cur = mod
    rest = list(segs)
    if not rest:
        return mod
    head = rest[0]
    if head == "crate":
        cur, rest = crate.root, rest[1:]
    elif head in ("self", "super"):
        while rest and rest[0] in ("self", "super"):
            if rest[0] == "super":
                if cur.parent is None:
                    return None
                cur = cur.parent
            rest = rest[1:]
    elif head in mod.children:
        pass
    elif head in mod.uses:
        target = mod.uses[head][0]
        if target == segs:
            return None
        return resolve_from(crate, mod, target, rest[1:], seen)
    else:
        return None  # an extern crate, or a name of the prelude
    return walk(crate, cur, rest, seen)


def resolve_from(crate, mod, target, rest, seen):
    base = resolve(crate, mod, tuple(target), seen) if target[0] in ("crate", "self", "super") or target[0] in mod.children else None
    if base is None:
        return None
    # `target` names a module: continue inside it; an item: stop at its module.
    node = find_module(crate, mod, tuple(target))
    if node is not None:
        return walk(crate, node, list(rest), seen)
    return base


def find_module(crate, mod, segs):
    cur = mod
    rest = list(segs)
    if rest and rest[0] == "crate":
        cur, rest = crate.root, rest[1:]
    while rest and rest[0] in ("self", "super"):
        if rest[0] == "super":
            if cur.parent is None:
                return None
            cur = cur.parent
        rest = rest[1:]
    for s in rest:
        if s in cur.children:
            cur = cur.children[s]
        else:
            return None
    return cur


def walk(crate, cur: Module, rest: list[str], seen):
    while rest:
        s = rest[0]
        if s in cur.children:
            cur, rest = cur.children[s], rest[1:]
            continue
        if s in cur.items:
            return cur
        if s in cur.uses:
            for target in cur.uses[s]:
                r = resolve_from(crate, cur, target, rest[1:], seen)
                if r is not None:
                    return r
            return cur
        for g in cur.globs:
            gm = find_module(crate, cur, g)
            if gm is not None and gm is not cur and defines(gm, s, set()):
                return walk(crate, gm, rest, seen)
        return cur
    return cur


def defines(mod: Module, name: str, seen: set) -> bool:
    if id(mod) in seen:
        return False
    seen.add(id(mod))
    return name in mod.items or name in mod.uses or name in mod.children


def is_ancestor(a: Module, b: Module) -> bool:
    while b is not None:
        if b is a:
            return True
        b = b.parent
    return False


def branch_edge(src: Module, dst: Module):
    """(common ancestor, child of it above src, child of it above dst) or None."""
    if is_ancestor(src, dst) or is_ancestor(dst, src):
        return None
    chain = []
    m = src
    while m is not None:
        chain.append(m)
        m = m.parent
    d = dst
    prev_d = None
    while d is not None and d not in chain:
        prev_d, d = d, d.parent
    lca = d
    prev_s = chain[chain.index(lca) - 1]
    return lca, prev_s, prev_d


def sccs(nodes, edges):
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = [0]

    def strong(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            out.append(comp)

    for v in nodes:
        if v not in index:
            strong(v)
    return out


def check(root_file: Path, tests: bool) -> list[str]:
    crate = Crate(root_file, tests)
    collect(crate)
    # (lca path) -> {src child name -> {dst child name -> [evidence]}}
    graphs: dict[tuple, dict[str, dict[str, list[str]]]] = {}
    for mod in crate.modules():
        for segs, line in mod.refs:
            dst = resolve(crate, mod, segs)
            if dst is None or dst is mod:
                continue
            e = branch_edge(mod, dst)
            if e is None:
                continue
            lca, a, b = e
            rel = mod.file.relative_to(ROOT) if mod.file.is_relative_to(ROOT) else mod.file
            ev = f"{rel}:{line} ({mod.name()} uses {'::'.join(segs)})"
            graphs.setdefault(lca.path, {}).setdefault(a.path[-1], {}).setdefault(b.path[-1], []).append(ev)
    problems = list(crate.errors)
    for lca_path, g in sorted(graphs.items()):
        nodes = sorted(set(g) | {d for v in g.values() for d in v})
        edges = {v: sorted(ds) for v, ds in g.items()}
        for comp in sccs(nodes, edges):
            if len(comp) < 2:
                continue
            comp = sorted(comp)
            where = "::".join(("crate",) + lca_path)
            lines = [f"{root_file.relative_to(ROOT)}: cycle among the modules of {where}: {' <-> '.join(comp)}"]
            for a in comp:
                for b in sorted(g.get(a, {})):
                    if b in comp:
                        ev = g[a][b]
                        lines.append(f"    {a} -> {b}: {ev[0]}" + (f" (+{len(ev) - 1} more)" if len(ev) > 1 else ""))
            problems.append("\n".join(lines))
    return problems


def crate_roots(args: list[str]) -> list[Path]:
    dirs = [Path(a).resolve() for a in args] or sorted(ROOT.glob("crates/*/src")) + [ROOT / "python" / "src"]
    roots = []
    for d in dirs:
        for name in ("lib.rs", "main.rs"):
            if (d / name).is_file():
                roots.append(d / name)
    return roots


def main() -> int:
    args = sys.argv[1:]
    tests = "--tests" in args
    args = [a for a in args if a != "--tests"]
    known: set[str] = set()
    if "--known" in args:
        i = args.index("--known")
        for line in Path(args[i + 1]).read_text(encoding="utf-8").splitlines():
            if line.strip() and not line.startswith("#"):
                known.add(line.strip())
        del args[i : i + 2]
    roots = crate_roots(args)
    problems = []
    for r in roots:
        problems += check(r, tests)
    new = [p for p in problems if p.splitlines()[0] not in known]
    seen = {p.splitlines()[0] for p in problems}
    for p in problems:
        if p not in new:
            print("known: " + p)
    for k in sorted(known - seen):
        print(f"note: no longer a cycle, remove it from the list of known cycles: {k}")
    for p in new:
        print(p)
    if new:
        print(f"error: {len(new)} module import cycle(s) (scripts/check_cycles.py)", file=sys.stderr)
        return 1
    print(
        f"no new module import cycles in {len(roots)} crates"
        + (f" ({len(problems)} known, listed above)" if problems else "")
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
