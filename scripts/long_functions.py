#!/usr/bin/env python3
"""Library functions longer than a limit (developers' guide: none over ~120 lines).

Usage: scripts/long_functions.py [DIR] [LIMIT]   (defaults: libwheelchair 120)
Prints "lines file:line name" per function over LIMIT, longest first; exit 1 when any is.
A function counts from the line of its opening brace to its closing brace; comments and
string literals are ignored, lambdas and local classes count in the function that holds them,
a constructor from the brace after its initializer list.
"""
import os
import re
import sys

KEYWORDS = {"if", "for", "while", "switch", "catch", "return", "sizeof", "decltype", "alignof",
            "static_assert"}


def strip(src):
    """The source without comments and literals (newlines kept)."""
    out, i, n = [], 0, len(src)
    while i < n:
        c = src[i]
        if src.startswith("//", i):
            j = src.find("\n", i)
            i = n if j < 0 else j
            continue
        if src.startswith("/*", i):
            j = src.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append("\n" * src[i:j].count("\n"))
            i = j
            continue
        if src.startswith('R"(', i):
            j = src.find(')"', i + 3)
            j = n if j < 0 else j + 2
            out.append('""' + "\n" * src[i:j].count("\n"))
            i = j
            continue
        if c in "\"'":
            j = i + 1
            while j < n and src[j] != c:
                j += 2 if src[j] == "\\" else 1
            out.append(c + c)
            i = j + 1
            continue
        out.append(c)
        i += 1
    return "".join(out)


def function_name(before_brace):
    """The name of the function whose body opens after this text, or None."""
    pre = re.sub(r"(\s*(const|override|noexcept|mutable|final|->\s*[\w:<>&*, ]+))*$", "",
                 before_brace.rstrip())
    if not pre.endswith(")"):
        return None
    depth, k = 0, len(pre) - 1
    while k >= 0:
        if pre[k] == ")":
            depth += 1
        elif pre[k] == "(":
            depth -= 1
            if depth == 0:
                break
        k -= 1
    before = pre[:k].rstrip()
    m = re.search(r"([~\w:]+)\s*(<[^<>]*>)?$", before)
    if not m or before.endswith("]") or m.group(1).split("::")[-1] in KEYWORDS:
        return None
    return m.group(1)


def long_functions(path, limit):
    s = strip(open(path, encoding="utf-8").read())
    stack, found = [], []  # (outermost function?, first line, name)
    for m in re.finditer(r"[{}]", s):
        pos = m.start()
        if s[pos] == "{":
            name = function_name(s[:pos])
            inside = any(f for f, _, _ in stack)
            stack.append((name is not None and not inside, s.count("\n", 0, pos) + 1, name))
        elif stack:
            is_function, first, name = stack.pop()
            lines = s.count("\n", 0, pos) + 1 - first + 1
            if is_function and lines > limit:
                found.append((lines, path, first, name))
    return found


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else "libwheelchair"
    limit = int(sys.argv[2]) if len(sys.argv) > 2 else 120
    found = []
    for d, _, files in os.walk(root):
        for f in sorted(files):
            if f.endswith((".cpp", ".h")):
                found += long_functions(os.path.join(d, f), limit)
    for lines, path, first, name in sorted(found, reverse=True):
        print(f"{lines:4d} {path}:{first} {name}")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
