#!/usr/bin/env bash
# Builds the documentation site with `mkdocs build --strict` (every page in the
# nav exists, every link between pages resolves) and checks every link and
# anchor of the built HTML (check_site_links.py: MkDocs 1.4 does not check
# anchors), and that the search answers the first questions (check_search.py).
#   site_test.sh SOURCE_DIR SITE_DIR
set -euo pipefail
source_dir=$1
site_dir=$2
if ! command -v mkdocs >/dev/null; then
  echo "site_test: mkdocs is not installed (Debian's mkdocs; scripts/test installs it)" >&2
  exit 1
fi
rm -rf "$site_dir"
mkdocs build --strict --quiet -f "$source_dir/mkdocs.yml" -d "$site_dir"
# Debian's interpreter, which sees Debian's python3-lunr (mkdocs depends on it);
# another python3 first on PATH may not.
py=python3
if [ -x /usr/bin/python3 ]; then py=/usr/bin/python3; fi
"$py" "$source_dir/tests/docs/check_site_links.py" "$site_dir"
# The first hit of the site's search for a reader's first questions.
"$py" "$source_dir/tests/docs/check_search.py" "$site_dir"
