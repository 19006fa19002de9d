#!/usr/bin/env python3
"""Checks the size rules of the README's "Development" section: no function over MAX_FUNCTION lines and
no source file over MAX_FILE lines in the library targets and apps/, unless the comment line just
above a function's first line says why with "long function:" (e.g. "// long function: one table of
options, read top to bottom").

    check_code_size.py [ROOT] [--max-function N] [--max-file N]

Functions are found by shape, the way clang-format lays them out here: a line at column 0 that is
not a comment, preprocessor line, namespace, type or `}` and holds a `(`, whose body opens on that
line or a following one; the body ends where its braces balance (braces in string and character
literals and in comments are skipped). Methods defined inside a class body are not measured.
Prints each offender as FILE:LINE NAME (N lines) and exits 1 if any, else 0.
"""
import argparse
import os
import re
import sys

FOLDERS = ["libmap", "crater", "registration", "landmarks", "adjustment", "pipeline", "apps",
           "samples"]
NOT_A_FUNCTION = ("//", "#", "namespace", "}", "struct", "class", "enum", "using", "template",
                  "extern", "typedef", "static_assert", "union")


def code_only(line, in_comment):
    """The line without literals and comments; and whether a /* comment is still open."""
    out = []
    i = 0
    quote = None
    while i < len(line):
        c = line[i]
        if in_comment:
            if line.startswith("*/", i):
                in_comment = False
                i += 2
                continue
            i += 1
            continue
        if quote:
            if c == "\\":
                i += 2
                continue
            if c == quote:
                quote = None
            i += 1
            continue
        if line.startswith("//", i):
            break
        if line.startswith("/*", i):
            in_comment = True
            i += 2
            continue
        if c in "\"'":
            # A raw string R"(...)" on one line is treated as a plain literal.
            quote = c
            i += 1
            continue
        out.append(c)
        i += 1
    return "".join(out), in_comment


def long_functions(path, max_lines):
    with open(path, encoding="utf-8", errors="replace") as f:
        lines = f.read().split("\n")
    code = []
    in_comment = False
    for line in lines:
        text, in_comment = code_only(line, in_comment)
        code.append(text)
    found = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if (line and not line[0].isspace() and not line.startswith(NOT_A_FUNCTION)
                and "(" in code[i]):
            # The body's opening brace, unless a ';' ends a declaration first.
            j = i
            while j < len(lines) and "{" not in code[j] and ";" not in code[j]:
                j += 1
            if j < len(lines) and "{" in code[j] and (";" not in code[j] or
                                                        code[j].index("{") < code[j].index(";")):
                depth = 0
                k = j
                started = False
                while k < len(lines):
                    for c in code[k]:
                        if c == "{":
                            depth += 1
                            started = True
                        elif c == "}":
                            depth -= 1
                    if started and depth <= 0:
                        break
                    k += 1
                length = k - i + 1
                above = lines[i - 1] if i > 0 else ""
                if length > max_lines and "long function:" not in above:
                    name = re.search(r"([A-Za-z_][A-Za-z0-9_:~]*)\s*\(", code[i])
                    found.append((i + 1, name.group(1) if name else line[:40], length))
                i = k + 1
                continue
        i += 1
    return found


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("root", nargs="?", default=os.path.join(os.path.dirname(__file__), ".."))
    parser.add_argument("--max-function", type=int, default=80)
    parser.add_argument("--max-file", type=int, default=800)
    args = parser.parse_args()
    offenders = 0
    for folder in FOLDERS:
        for directory, _, files in os.walk(os.path.join(args.root, folder)):
            for name in sorted(files):
                if not name.endswith((".cc", ".h")):
                    continue
                path = os.path.join(directory, name)
                shown = os.path.relpath(path, args.root)
                with open(path, encoding="utf-8", errors="replace") as f:
                    count = f.read().count("\n")
                if count > args.max_file:
                    print(f"{shown}: {count} lines, over {args.max_file}: split the file")
                    offenders += 1
                for line, function, length in long_functions(path, args.max_function):
                    print(f"{shown}:{line} {function} ({length} lines, over "
                          f"{args.max_function}: split it into named steps, or say why above it "
                          f"with 'long function:')")
                    offenders += 1
    if offenders:
        return 1
    print(f"check_code_size: no function over {args.max_function} lines, no file over "
          f"{args.max_file} lines")
    return 0


if __name__ == "__main__":
    sys.exit(main())
