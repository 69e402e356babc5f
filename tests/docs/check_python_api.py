#!/usr/bin/env python3
"""Every name the Python package exports is on the Python API page.

Reads the names the bindings define (python/src/module.cpp: `.def("name"`,
`.def_static`, `.def_property`, `.def_property_readonly`, `m.def("name"`,
`m.attr("NAME")`, registered exceptions) and the package's `__all__`
(python/blot/__init__.py), and fails naming each one that
docs/reference/python-api.md does not mention as `name`.

    tests/docs/check_python_api.py [--bindings FILE] [--package FILE] [--page FILE]
"""
import argparse
import os
import re
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
DEF = re.compile(r"\.(?:def|def_static|def_property|def_property_readonly|def_readonly|def_readwrite)\(\s*\"(\w+)\"")
ATTR = re.compile(r"\bm\.attr\(\s*\"(\w+)\"\s*\)")
EXCEPTION = re.compile(r"register_exception<[^>]*>\(\s*\w+\s*,\s*\"(\w+)\"")
ALL = re.compile(r"__all__\s*=\s*\[([^\]]*)\]", re.S)


def main(argv):
    ap = argparse.ArgumentParser()
    ap.add_argument("--bindings", default=os.path.join(ROOT, "python", "src", "module.cpp"))
    ap.add_argument("--package", default=os.path.join(ROOT, "python", "blot", "__init__.py"))
    ap.add_argument("--page", default=os.path.join(ROOT, "docs", "reference", "python-api.md"))
    args = ap.parse_args(argv)
    code = open(args.bindings, encoding="utf-8").read()
    names = set(DEF.findall(code)) | set(ATTR.findall(code)) | set(EXCEPTION.findall(code))
    for group in ALL.findall(open(args.package, encoding="utf-8").read()):
        names.update(re.findall(r"[\"'](\w+)[\"']", group))
    names = {n for n in names if not n.startswith("_")}
    page = open(args.page, encoding="utf-8").read()
    # `name`, `name(...)`, `Engine.name(...)`: a code span that starts with the name.
    mentioned = set(re.findall(r"`(?:\w+\.)*(\w+)", page))
    missing = sorted(names - mentioned)
    rel = os.path.relpath(args.page, ROOT)
    for n in missing:
        print(f"{rel}: `{n}` is defined by the Python package but not documented")
    if missing or not names:
        print(f"check_python_api: {len(missing)} of {len(names)} names undocumented", file=sys.stderr)
        return 1
    print(f"check_python_api: all {len(names)} names of the Python package are on {rel}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
