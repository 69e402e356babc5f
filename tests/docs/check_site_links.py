#!/usr/bin/env python3
"""Checks every link and anchor of a built MkDocs site.

MkDocs 1.4's --strict catches a link to a missing page but not a missing
anchor (`page.md#no-such-heading`). This walks the built HTML (but 404.html,
whose links start at the site's root), collects each
page's ids, and checks that every relative href/src names a file of the site
and, when it has a fragment, an id on that page. External links (http:, https:,
mailto:) are not fetched.

    tests/docs/check_site_links.py SITE_DIR
"""
import html.parser
import os
import sys
import urllib.parse

SKIP_SCHEMES = ("http:", "https:", "mailto:", "javascript:", "data:", "ftp:", "//")


class Page(html.parser.HTMLParser):
    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.ids = set()
        self.links = []  # (line, attribute value)

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if value is None:
                continue
            if name in ("id",) or (name == "name" and tag == "a"):
                self.ids.add(value)
            if (name == "href" and tag in ("a", "link")) or (name == "src" and tag in ("img", "script")):
                self.links.append((self.getpos()[0], value))


def main(argv):
    if len(argv) != 1:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    site = os.path.abspath(argv[0])
    pages = {}
    for dirpath, _, filenames in os.walk(site):
        for name in filenames:
            # 404.html is served at whatever address was not found, so MkDocs
            # writes its links from the site's root ("/index.html"): not relative.
            if name.endswith(".html") and not (dirpath == site and name == "404.html"):
                path = os.path.join(dirpath, name)
                page = Page()
                page.feed(open(path, encoding="utf-8", errors="replace").read())
                pages[path] = page
    if not pages:
        print(f"check_site_links: no HTML under {site}", file=sys.stderr)
        return 2
    broken = 0
    checked = 0
    for path, page in sorted(pages.items()):
        for line, link in page.links:
            if link.startswith(SKIP_SCHEMES) or link in ("", "#"):
                continue
            checked += 1
            parts = urllib.parse.urlsplit(link)
            target = path
            if parts.path:
                target = os.path.normpath(os.path.join(os.path.dirname(path), urllib.parse.unquote(parts.path)))
                if os.path.isdir(target):
                    target = os.path.join(target, "index.html")
            where = f"{os.path.relpath(path, site)}:{line}"
            if not target.startswith(site + os.sep) and target != site:
                print(f"{where}: {link}: leaves the site")
                broken += 1
                continue
            if not os.path.exists(target):
                print(f"{where}: {link}: no such file")
                broken += 1
                continue
            fragment = urllib.parse.unquote(parts.fragment)
            if fragment and target.endswith(".html"):
                ids = pages[target].ids if target in pages else set()
                if fragment not in ids:
                    print(f"{where}: {link}: no anchor #{fragment} on {os.path.relpath(target, site)}")
                    broken += 1
    if broken:
        print(f"check_site_links: {broken} broken of {checked} links in {len(pages)} pages", file=sys.stderr)
        return 1
    print(f"check_site_links: {checked} links in {len(pages)} pages, all resolve")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
