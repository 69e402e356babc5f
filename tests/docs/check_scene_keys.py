#!/usr/bin/env python3
"""The scene-key reference cannot drift from the parser.

Reads every key the scene parser asks for (engine/src/scene.cpp: the
ObjectReader calls `x.number("key", ...)`, `x.integer`, `x.boolean`,
`x.choice`, `x.vector3`, `x.vector2`, `x.string`, `x.array`, `x.find`,
`x.has`, `x.require`, and every name in an `allowOnly({...})` list) and every
key the reference page lists (docs/scene-format.md: the backquoted names in
the first column of its tables, e.g. `patch.size` or `icosphere.radius`,
`disc.radius`; an object's keys in its type cell, {`face`, `direction`};
a key defined in prose as "`source` (**required**): ..."). Keys are compared by name, the way the parser's readers see
them: `patch.size` lists `size` and the object `patch` that holds it. Fails, naming them, when the parser
accepts a key the page does not list or the page lists a key the parser does
not accept.

    tests/docs/check_scene_keys.py [--parser FILE] [--page FILE]
"""
import argparse
import os
import re
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))

READER_CALL = re.compile(
    r"\b[A-Za-z_]\w*\s*(?:\.|->)\s*(?:number|integer|boolean|choice|vector3|vector2|string|array|find|has|require)"
    r"\s*\(\s*\"([A-Za-z_][A-Za-z0-9_]*)\"")
ALLOW_ONLY = re.compile(r"allowOnly\s*\(\s*\{([^}]*)\}", re.S)
STRING = re.compile(r"\"([A-Za-z_][A-Za-z0-9_]*)\"")
CODE_SPAN = re.compile(r"`([^`]+)`")
PROSE_KEY = re.compile(r"^`([A-Za-z_][A-Za-z0-9_]*)` \(\*\*required\*\*\)")
KEY_PATH = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(?:\[[^\]]*\])?(?:\.[A-Za-z_][A-Za-z0-9_]*(?:\[[^\]]*\])?)*$")


def strip_comments(text):
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    return re.sub(r"//[^\n]*", "", text)


def parser_keys(path):
    code = strip_comments(open(path, encoding="utf-8").read())
    keys = set(READER_CALL.findall(code))
    for group in ALLOW_ONLY.findall(code):
        keys.update(STRING.findall(group))
    return keys


def page_keys(path):
    keys = {}
    for number, line in enumerate(open(path, encoding="utf-8"), 1):
        # A key defined in prose: "`source` (**required**): ...".
        m = PROSE_KEY.match(line)
        if m:
            keys.setdefault(m.group(1), number)
        if not line.startswith("|"):
            continue
        cells = re.split(r"(?<!\\)\|", line.strip().strip("|"))
        first = cells[0].strip()
        if not first or set(first) <= set("-: "):
            continue
        for span in CODE_SPAN.findall(first):
            span = span.strip()
            if not KEY_PATH.match(span):
                continue
            # `preview.width` lists `width` and, as the object that holds it, `preview`.
            for name in re.sub(r"\[[^\]]*\]", "", span).split("."):
                keys.setdefault(name, number)
        # An object's own keys spelled in its type: {`face`, `direction`} or {`"label"`: L}.
        if len(cells) > 1:
            for group in re.findall(r"\{([^}]*)\}", cells[1]):
                for span in CODE_SPAN.findall(group):
                    name = span.strip().strip('"')
                    if KEY_PATH.match(name):
                        keys.setdefault(name, number)
    return keys


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument("--parser", default=os.path.join(ROOT, "engine", "src", "scene.cpp"))
    ap.add_argument("--page", default=os.path.join(ROOT, "docs", "scene-format.md"))
    args = ap.parse_args(argv)
    accepted = parser_keys(args.parser)
    listed = page_keys(args.page)
    if not accepted:
        print(f"check_scene_keys: found no keys in {args.parser}; has the reader's interface changed?", file=sys.stderr)
        return 2
    if not listed:
        print(f"check_scene_keys: found no key tables in {args.page}", file=sys.stderr)
        return 2
    undocumented = sorted(accepted - set(listed))
    unknown = sorted(set(listed) - accepted)
    page = os.path.relpath(args.page, ROOT)
    for key in undocumented:
        print(f"{page}: undocumented key: `{key}` is accepted by {os.path.relpath(args.parser, ROOT)} "
              f"but listed in no table of the page")
    for key in unknown:
        print(f"{page}:{listed[key]}: unknown key: `{key}` is listed but the parser does not accept it")
    if undocumented or unknown:
        print(f"check_scene_keys: {len(undocumented)} undocumented, {len(unknown)} unknown "
              f"({len(accepted)} keys accepted, {len(listed)} listed)", file=sys.stderr)
        return 1
    print(f"check_scene_keys: the {len(accepted)} keys the parser accepts are the keys {page} lists")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
