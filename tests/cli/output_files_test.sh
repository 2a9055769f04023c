#!/usr/bin/env bash
# The tools write only files they made (idl/common/output_file.hpp, bin/cell_output.py): a run
# into the folder of the last run writes over the last run's files, but a user's file of one
# of our names, or a link planted where an output goes, is refused in one line naming it, and
# the file (or the one the link points to) is left as it was. Every writer is tried: the
# tables and images of decode-sweep, render's image and truth, servo decode's JSON and overlay,
# the calibration, the pattern, an experiment's trace and its plots (drawn by Python).
set -u
bin="$1"; src="$2"
source "$(dirname "$0")/lib.sh"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
cellsim="$bin/cellsim"; servo="$bin/servo"; pattern="$src/servo/pattern/data/marray_20x20_k3_w3.txt"
plane="$src/sim/scenarios/plane.yaml"
echo precious > "$tmp/victim"
intact() { [ "$(cat "$tmp/victim")" = precious ] || fail "$1: the file a link points to was written"; }
mine() { echo "my notes" > "$1"; }
kept() { [ "$(cat "$1")" = "my notes" ] || fail "$1: a user's file was written over"; }

# decode-sweep: a link, then a user's file, in place of sweep.csv; then two runs into one folder
mkdir "$tmp/sweep"; ln -s "$tmp/victim" "$tmp/sweep/sweep.csv"
one_line_error "sweep.csv a link" "sweep.csv: is a symbolic link" "$cellsim" decode-sweep "$plane" --poses 2 -o "$tmp/sweep"
intact "decode-sweep"
rm "$tmp/sweep/sweep.csv"; mine "$tmp/sweep/sweep.csv"
one_line_error "sweep.csv the user's" "sweep.csv: exists and was not written here" "$cellsim" decode-sweep "$plane" --poses 2 -o "$tmp/sweep"
kept "$tmp/sweep/sweep.csv"
"$cellsim" decode-sweep "$plane" --poses 2 -o "$tmp/again" >/dev/null 2>&1 || fail "decode-sweep into a new folder"
"$cellsim" decode-sweep "$plane" --poses 3 -o "$tmp/again" >/dev/null 2>&1 || fail "decode-sweep again into its own folder"
[ "$(grep -vc '^pose' "$tmp/again/sweep.csv")" -eq 3 ] || fail "the second sweep's table is not the one left"

# render: the image and the truth
mine "$tmp/desired.png"
one_line_error "render over the user's image" "desired.png: exists and was not written here" "$cellsim" render "$plane" --pose desired -o "$tmp/desired.png"
kept "$tmp/desired.png"
ln -s "$tmp/victim" "$tmp/truth.json"
one_line_error "render's truth a link" "truth.json: is a symbolic link" "$cellsim" render "$plane" --pose desired -o "$tmp/d.png" --truth "$tmp/truth.json"
intact "render --truth"
"$cellsim" render "$plane" --pose desired -o "$tmp/d.png" >/dev/null || fail "render"
"$cellsim" render "$plane" --pose desired -o "$tmp/d.png" >/dev/null || fail "render again over its own image"

# servo decode: its JSON and its overlay
mine "$tmp/d.json"
one_line_error "decode's JSON the user's" "d.json: exists and was not written here" "$servo" decode "$tmp/d.png" --pattern "$pattern" --json "$tmp/d.json"
kept "$tmp/d.json"
ln -s "$tmp/victim" "$tmp/overlay.png"
one_line_error "decode's overlay a link" "overlay.png: is a symbolic link" "$servo" decode "$tmp/d.png" --pattern "$pattern" --overlay "$tmp/overlay.png"
intact "servo decode --overlay"

# servo run's taught reference: a link in its place is refused before the servo joins DDS
# (a link to a file that is not there: one to a file would be read as the reference)
ln -s "$tmp/planted.json" "$tmp/ref.json"
one_line_error "servo run's reference a link" "ref.json: is a symbolic link" timeout 30 "$servo" run --pattern "$pattern" --reference "$tmp/ref.json"
[ ! -e "$tmp/planted.json" ] || fail "servo run wrote through the link in its reference's place"

# the calibration and the pattern
mine "$tmp/cal.yaml"
one_line_error "calibration over the user's file" "cal.yaml: exists and was not written here" "$cellsim" calibration "$plane" -o "$tmp/cal.yaml"
kept "$tmp/cal.yaml"
mine "$tmp/p.txt"
one_line_error "pattern over the user's file" "p.txt: exists and was not written here" "$bin/pattern" generate --rows 8 --cols 8 --colours 3 --seed 1 -o "$tmp/p.txt"
kept "$tmp/p.txt"

# an experiment: its trace, and a plot that Python draws
mkdir "$tmp/exp"; mine "$tmp/exp/trace.csv"
one_line_error "experiment over the user's trace" "trace.csv: exists and was not written here" "$cellsim" experiment "$plane" --max-iterations 5 -o "$tmp/exp"
kept "$tmp/exp/trace.csv"
rm "$tmp/exp/trace.csv"; ln -s "$tmp/victim" "$tmp/exp/velocities.png"
err=$("$cellsim" experiment "$plane" --max-iterations 5 -o "$tmp/exp" 2>&1 >/dev/null)
grep -q "velocities.png: is a symbolic link" <<<"$err" || fail "the plot script wrote through a link: $err"
intact "plot_trace.py"
# a campaign checks the files it writes at its end before it runs
mkdir "$tmp/camp"; mine "$tmp/camp/summary.md"
one_line_error "campaign over the user's summary" "summary.md: exists and was not written here" "$cellsim" campaign "$plane" --runs 1 --max-iterations 5 -o "$tmp/camp"
kept "$tmp/camp/summary.md"
[ ! -e "$tmp/camp/campaign.csv" ] || fail "the campaign ran before it was refused"
# the list of what was written is not a way in either
mkdir "$tmp/list"; ln -s "$tmp/victim" "$tmp/list/.cell-written"
one_line_error "the list a link" ".cell-written" "$cellsim" render "$plane" --pose desired -o "$tmp/list/x.png"
intact "the list"
echo "output files: only the tools' own are written over"
