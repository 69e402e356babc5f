#!/usr/bin/env python3
"""The site's search sends a reader's first questions to the right page.

Builds the same lunr index the site's search builds in the browser (MkDocs's
search_index.json; title boosted 10, as its search worker does; Debian's
python3-lunr, which mkdocs depends on) and requires the first hit for each
query to be the page that answers it.

    tests/docs/check_search.py SITE_DIR
"""
import json
import os
import sys

from lunr import lunr

EXPECTED = {
    "Table 1": "performance.html#table-1",
    "blotEngine_Step": "reference/c-api.html#blotengine_step",
    "absorption_rate": "scene-format.html#liquid",
}


def main(argv):
    if len(argv) != 1:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    data = json.load(open(os.path.join(argv[0], "search", "search_index.json"), encoding="utf-8"))
    index = lunr(ref="location", fields=[dict(field_name="title", boost=10), "text"], documents=data["docs"])
    failed = 0
    for query, page in EXPECTED.items():
        hits = [h["ref"] for h in index.search(query)]
        first = hits[0] if hits else None
        if first != page:
            print(f"check_search: the first hit for '{query}' is {first}, expected {page} (then: {hits[1:4]})")
            failed += 1
        else:
            print(f"check_search: '{query}' -> {page}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
