#!/usr/bin/env bash
# bin/decode-heldout as a user runs it (issue 41, Held-out test), on 2 poses a case: every
# scene and condition swept, the table, the CSV and the plot written; an existing output
# folder refused, nothing written over; a run compared with an earlier one (--against), and
# the earlier runs it cannot be compared with refused.
set -u
src="$1"; build="$2"
source "$(dirname "$0")/lib.sh"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
out=$(BUILD_DIR="$build" "$src/bin/decode-heldout" -o "$tmp/h" --poses 2 2>&1) || fail "bin/decode-heldout: $out"
for f in decode.csv decode.md decode.png losses.png law.png; do [ -s "$tmp/h/$f" ] || fail "no $f"; done
rows=$(($(wc -l <"$tmp/h/decode.csv") - 1))
[ "$rows" -eq 192 ] || fail "$rows cases in decode.csv, not 16 scenes x 6 conditions x 2"
grep -q "^heldout,bottle,printed," "$tmp/h/decode.csv" && grep -q "^tuning,box,printed," "$tmp/h/decode.csv" || fail "no printed bottle or box: $(head -3 "$tmp/h/decode.csv")"
grep -q "^| step | " "$tmp/h/decode.md" && grep -q "^| wedge | " "$tmp/h/decode.md" ||
  fail "the tables lack the step or the wedge: $(cat "$tmp/h/decode.md")"
# why the segmented readable spots have no id: the causes in the CSV, both tables in the markdown
head -1 "$tmp/h/decode.csv" | grep -q ",lost_border,.*,lost_nearer_line" || fail "decode.csv lacks the loss causes"
grep -q "^| set | shape | no id | border | dropped |" "$tmp/h/decode.md" && grep -q "| nearer line |" "$tmp/h/decode.md" ||
  fail "decode.md lacks the loss tables: $(cat "$tmp/h/decode.md")"
# how far a labelling could go: the table, and decode-sweep's accounting behind it (a segmented
# readable spot is identified or lost for exactly one cause, so none is named beyond the blobs)
grep -q "^\*\*What a labelling could name\*\*" "$tmp/h/decode.md" && grep -q "^| step | .* / .* % |" "$tmp/h/decode.md" ||
  fail "decode.md lacks what a labelling could name: $(cat "$tmp/h/decode.md")"
unaccounted=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) col[$i] = i; next }
  { lost = 0; for (k in col) if (k ~ /^lost_/) lost += $col[k]
    if ($col["segmented"] != $col["identified"] + lost) print $col["shape"], $col["condition"] }' "$tmp/h/decode.csv")
[ -z "$unaccounted" ] || fail "segmented readable spots neither identified nor lost for a cause: $unaccounted"
# what reaches the control law: the table, and every id that reaches it counted once by what it is
grep -q "^\*\*What reaches the control law\*\*" "$tmp/h/decode.md" && grep -q "^| step | [0-9]* of [0-9]* · [0-9]* of [0-9]* |" "$tmp/h/decode.md" ||
  fail "decode.md lacks what reaches the law: $(cat "$tmp/h/decode.md")"
miscounted=$(awk -F, '{ sub(/\r$/, "") }  # (the csv module ends its lines in CR LF)
  NR == 1 { for (i = 1; i <= NF; i++) col[$i] = i; next }
  { if ($col["to_law"] != $col["to_law_right"] + $col["to_law_mislocated"] + $col["to_law_partial"] + $col["to_law_wrong"] ||
        $col["to_law_partial"] > $col["partial"] || $col["to_law_wrong"] > $col["wrong_ids"]) print $col["shape"], $col["condition"] }' "$tmp/h/decode.csv")
[ -z "$miscounted" ] || fail "ids reaching the law not counted once by kind: $miscounted"
one_line_error "an existing output folder" "exists" env BUILD_DIR="$build" "$src/bin/decode-heldout" -o "$tmp/h" --poses 2
one_line_error "an unknown condition" "unknown" env BUILD_DIR="$build" "$src/bin/decode-heldout" -o "$tmp/c" --conditions grey,shiny
[ ! -e "$tmp/c" ] || fail "an unknown condition made its output folder"
one_line_error "a pattern that is no file" "not a regular file" env BUILD_DIR="$build" "$src/bin/decode-heldout" -o "$tmp/p" --pattern "$tmp"
[ ! -e "$tmp/p" ] || fail "a pattern that is no file made its output folder"
# the paper's pattern in place of the scenes': every case swept with it, the table says so
out=$(BUILD_DIR="$build" "$src/bin/decode-heldout" -o "$tmp/q" --poses 1 --set tuning --conditions grey \
  --pattern "$src/servo/pattern/data/marray_20x20_k3_w3.txt" 2>&1) || fail "decode-heldout --pattern: $out"
grep -q -- "--pattern servo/pattern/data/marray_20x20_k3_w3.txt" "$tmp/q/decode.md" || fail "the table does not name the pattern"
# and it reaches every sweep: a file that is no pattern stops the first one, in one line
one_line_error "a file that is no pattern" "README.md" env BUILD_DIR="$build" "$src/bin/decode-heldout" -o "$tmp/r" \
  --poses 1 --set tuning --conditions grey --pattern "$src/README.md"
[ "$(($(wc -l <"$tmp/q/decode.csv") - 1))" -eq 22 ] || fail "not 11 scenes x 1 condition x 2 with the paper's pattern"
# the white reference frame for every sweep, against the first run (the same frames): the table
# says so, printed cases name more, and the comparison counts what the two tables hold
out=$(BUILD_DIR="$build" "$src/bin/decode-heldout" -o "$tmp/w" --poses 2 --set tuning --conditions printed \
  --white-frame --against "$tmp/h" 2>&1) || fail "decode-heldout --white-frame --against: $out"
grep -q -- "--white-frame" "$tmp/w/decode.md" || fail "the table does not say the white frame was taken"
more=$(awk -F, 'NR == FNR { if (FNR > 1) a[$2 "," $3 "," $4] = $7; next } FNR > 1 && $7 > a[$2 "," $3 "," $4] { n++ } END { print n + 0 }' \
  "$tmp/h/decode.csv" "$tmp/w/decode.csv")
[ "$more" -ge 8 ] || fail "with the white frame only $more of the 12 printed tuning cases name more spots"
for f in run.json against.md against.csv against.png; do [ -s "$tmp/w/$f" ] || fail "--against wrote no $f"; done
grep -q -- "--white-frame\` against \`bin/decode-heldout --poses 2 --seed 1\`" "$tmp/w/against.md" ||
  fail "against.md does not name both runs: $(head -1 "$tmp/w/against.md")"
[ "$(($(wc -l <"$tmp/w/against.csv") - 1))" -eq 22 ] || fail "against.csv: not the 22 printed tuning cases"
gained=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) col[$i] = i; next }
  $col["identified_after"] > $col["identified_before"] { n++ } END { print n + 0 }' "$tmp/w/against.csv")
[ "$gained" -eq "$more" ] || fail "against.csv has $gained cases naming more, the two tables $more"
# an earlier run of other frames, or no run, or a table that is not one: one line, nothing written
one_line_error "--against a run of another pattern" "not the same frames" env BUILD_DIR="$build" \
  "$src/bin/decode-heldout" -o "$tmp/a1" --poses 1 --set tuning --conditions grey --against "$tmp/q"
one_line_error "--against no folder" "not a folder" env BUILD_DIR="$build" "$src/bin/decode-heldout" -o "$tmp/a2" \
  --poses 2 --against "$tmp/none"
cp -r "$tmp/h" "$tmp/hb" && sed -i '3s/^\([a-z]*,[a-z]*,[a-z]*,[a-z]*,2,\)[0-9]*/\1x/' "$tmp/hb/decode.csv"
one_line_error "--against a table with a bad count" "line 3: readable is not a whole number" env BUILD_DIR="$build" \
  "$src/bin/decode-heldout" -o "$tmp/a3" --poses 2 --against "$tmp/hb"
for d in a1 a2 a3; do [ ! -e "$tmp/$d" ] || fail "a refused --against made its output folder $d"; done
# a decoder number set for every sweep: the table names it; one that is none stops the first sweep in one line
out=$(BUILD_DIR="$build" "$src/bin/decode-heldout" -o "$tmp/o" --poses 1 --set tuning --conditions grey \
  --decoder-option growth.faintest=0 2>&1) || fail "decode-heldout --decoder-option: $out"
grep -q -- "--decoder-option growth.faintest=0" "$tmp/o/decode.md" || fail "the table does not name the decoder option"
one_line_error "a decoder option that is none" "growth.nothing" env BUILD_DIR="$build" "$src/bin/decode-heldout" \
  -o "$tmp/n" --poses 1 --set tuning --conditions grey --decoder-option growth.nothing=1
echo "decode-heldout: 132 cases, the tables and the plot"
