#!/usr/bin/env bash
# Every URDF the project ships is well-formed XML to strict parsers: xmllint and Python's
# xml.etree refuse "--" inside a comment, which TinyXML2 lets through (issue 18, item 8).
set -u
src="$1"
source "$(dirname "$0")/lib.sh"
mapfile -t files < <(cd "$src" && git ls-files '*.urdf' 2>/dev/null || find . -name '*.urdf' -not -path './build*')
[ ${#files[@]} -gt 0 ] || fail "no URDF found under $src"
for f in "${files[@]}"; do
  xmllint --noout "$src/$f" 2>/dev/null || fail "$f: not well-formed XML (xmllint: $(xmllint --noout "$src/$f" 2>&1 | head -1))"
  /usr/bin/python3 -c 'import sys, xml.etree.ElementTree as E; E.parse(sys.argv[1])' "$src/$f" 2>/dev/null ||
    fail "$f: not well-formed XML (xml.etree)"
done
echo "urdf: ${#files[@]} files well-formed"
