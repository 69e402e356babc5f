#!/usr/bin/env python3
"""The scene-key reference cannot drift from the parser.

Reads every key the scene parser asks for (engine/src/scene.cpp: the
ObjectReader calls `x.number("key", ...)`, `x.integer`, `x.boolean`,
`x.choice`, `x.vector3`, `x.vector2`, `x.string`, `x.array`, `x.find`,
`x.has`, `x.require`, and every name in an `allowOnly({...})` list) and every
key the reference page lists (docs/scene-format.md: the backquoted names in
the first column of its tables, e.g. `patch.size` or `icosphere.radius`,
`disc.radius`; an object's keys in its type cell, {`face`, `direction`};
a key defined in prose as "`source` (**required**): ..."). Keys are compared
by name within their section: a parser function's keys (parsePhysics) against
the keys listed under the page's heading for it (`## physics`), so that
`physics.model` is not taken as documented by `cloth.wind.model`; `patch.size`
lists `size` and the object `patch` that holds it. Keys that a helper reads
for several sections (vertexOrPoint: pins, drops, held regions) may be listed
in any section. Fails, naming them, when the parser
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


# Which section of the page a parser function's keys belong to. Keys read
# elsewhere (a helper such as vertexOrPoint, shared by pins, drops and held
# regions) may be listed in any section.
SECTION_OF_FUNCTION = {
    "parseMesh": "mesh",
    "parsePin": "cloth", "parseCollider": "cloth", "parseBullet": "cloth", "parseCloth": "cloth",
    "parseTensor": "fabric", "parseFabric": "fabric",
    "parseLiquid": "liquid", "applyPreset": "liquid", "presetByName": "liquid",
    "parsePhysics": "physics",
    "parseDrop": "drops",
    "parseHeldRegion": "held regions",
    "parseOutputs": "outputs",
}
# parseScene reads the top level and the display itself, and the physics model.
SECTION_OF_SCENE_READER = {"r": "top level", "d": "display", "p": "physics"}
ANY = "*"
FUNCTION_START = re.compile(r"^[A-Za-z][\w:<>,&\* ]*?\b(\w+)\([^;{]*\)\s*(?:const\s*)?\{", re.M)
READER_CALL_NAMED = re.compile(
    r"\b([A-Za-z_]\w*)\s*(?:\.|->)\s*(?:number|integer|boolean|choice|vector3|vector2|string|array|find|has|require)"
    r"\s*\(\s*\"([A-Za-z_][A-Za-z0-9_]*)\"")


def parser_keys(path):
    """{(section, key)}: the section is the page's, or ANY."""
    code = strip_comments(open(path, encoding="utf-8").read())
    starts = [(m.start(), m.group(1)) for m in FUNCTION_START.finditer(code)]
    keys = set()
    for k, (start, function) in enumerate(starts):
        body = code[start:starts[k + 1][0] if k + 1 < len(starts) else len(code)]
        for reader, key in READER_CALL_NAMED.findall(body):
            if function == "parseScene":
                keys.add((SECTION_OF_SCENE_READER.get(reader, ANY), key))
            else:
                keys.add((SECTION_OF_FUNCTION.get(function, ANY), key))
        for group in ALLOW_ONLY.findall(body):
            section = "top level" if function == "parseScene" else SECTION_OF_FUNCTION.get(function, ANY)
            keys.update((section, key) for key in STRING.findall(group))
    return keys


def page_keys(path):
    """{(section, key): line}: the section is the `## ` heading above, lower case."""
    keys = {}
    section = ""
    for number, line in enumerate(open(path, encoding="utf-8"), 1):
        if line.startswith("## "):
            section = line[3:].strip().lower()
            continue
        # A key defined in prose: "`source` (**required**): ...".
        m = PROSE_KEY.match(line)
        if m:
            keys.setdefault((section, m.group(1)), number)
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
                keys.setdefault((section, name), number)
        # An object's own keys spelled in its type: {`face`, `direction`} or {`"label"`: L}.
        if len(cells) > 1:
            for group in re.findall(r"\{([^}]*)\}", cells[1]):
                for span in CODE_SPAN.findall(group):
                    name = span.strip().strip('"')
                    if KEY_PATH.match(name):
                        keys.setdefault((section, name), number)
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
    sections = {section for section, _ in accepted if section != ANY}
    listed_anywhere = {key for _, key in listed}
    undocumented = sorted(
        (section, key) for section, key in accepted
        if ((section, key) not in listed if section != ANY else key not in listed_anywhere))
    shared = {key for section, key in accepted if section == ANY}
    unknown = sorted(
        (section, key) for section, key in listed
        if section in sections and (section, key) not in accepted and key not in shared)
    page = os.path.relpath(args.page, ROOT)
    parser = os.path.relpath(args.parser, ROOT)
    for section, key in undocumented:
        where = "any table of the page" if section == ANY else f"the page's '{section}' section"
        print(f"{page}: undocumented key: `{key}` is accepted by {parser} but listed in no table of {where}")
    for section, key in unknown:
        print(f"{page}:{listed[(section, key)]}: unknown key: `{key}` is listed in the '{section}' section "
              f"but the parser does not accept it there")
    if undocumented or unknown:
        print(f"check_scene_keys: {len(undocumented)} undocumented, {len(unknown)} unknown "
              f"({len(accepted)} keys accepted, {len(listed)} listed)", file=sys.stderr)
        return 1
    print(f"check_scene_keys: the {len(accepted)} keys the parser accepts are the keys {page} lists")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
