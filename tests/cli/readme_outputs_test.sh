#!/usr/bin/env bash
# Every file or folder that README's commands write is ignored by git (issue 18, item 4): a
# user who runs the Tools block is left with a clean `git status`, and the keystore's private
# key never lands beside the sources.
set -u
src="$1"
source "$(dirname "$0")/lib.sh"
cd "$src" || fail "no $src"
git rev-parse --git-dir >/dev/null 2>&1 || { echo "SKIP: $src is not a git checkout"; exit 77; }
# the sh blocks of README.md
block=$(awk '/^```sh$/{on=1; next} /^```$/{on=0} on' README.md)
[ -n "$block" ] || fail "README.md has no sh block"
paths=$(grep -oE -- '(-o|--output|--truth|--overlay|--json|--json-dir|--trace|--white) [^ ]+' <<<"$block" | awk '{print $2}')
paths+=$'\n'$(grep -oE 'bin/keystore [^ ]+' <<<"$block" | awk '{print $2}')
n=0
while read -r p; do
  [ -z "$p" ] && continue
  case "$p" in meshes/|meshes) continue ;; esac  # make_meshes rewrites the committed meshes
  n=$((n + 1))
  git check-ignore -q --no-index "$p" || fail "README writes '$p', which git does not ignore"
done <<<"$paths"
[ "$n" -ge 10 ] || fail "found only $n output paths in README's commands"
echo "README: $n output paths, all ignored by git"
