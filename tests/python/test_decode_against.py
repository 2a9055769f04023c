"""bin/decode_against.py, what `bin/decode-heldout --against DIR` reads and writes: an earlier
run is compared only when it drew the same frames, its files are read as untrusted (regular,
bounded, every field checked), and the comparison counts what the two tables hold, setting apart
a case whose frames differ. No sweep: cli.decode_heldout runs the whole path."""
import csv
import json
import os
import sys

import pytest

sys.path.insert(0, os.path.join(os.environ["CELL_SOURCE_DIR"], "bin"))
import decode_against as da  # noqa: E402

RUN = {"poses": 2, "seed": 1, "pattern": "", "decoder_option": [], "fitted_lines": False, "taught_points": False,
       "white_frame": False}
COLUMNS = ["set", "shape", "condition", "calibration", "poses", "readable", "identified", "rate_pct", "wrong_ids",
           "mislocated", "partial", "to_law_partial", "to_law_wrong"]
CASES = {("tuning", "ham", "grey", "yes"), ("tuning", "ham", "grey", "no"), ("tuning", "egg", "grey", "yes")}


def row(shape="ham", cal="yes", readable=100, identified=90, wrong=0, poses=2):
    return {"set": "tuning", "shape": shape, "condition": "grey", "calibration": cal, "poses": poses,
            "readable": readable, "identified": identified, "rate_pct": "90.0", "wrong_ids": wrong, "mislocated": 3,
            "partial": 2, "to_law_partial": 1, "to_law_wrong": 0}


def earlier(tmp_path, rows, run=RUN):
    d = tmp_path / "base"
    d.mkdir()
    (d / "run.json").write_text(json.dumps(run))
    with open(d / "decode.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        w.writerows(rows)
    return d


def refused(folder, expect, run=RUN):
    with pytest.raises(da.Refused) as e:
        da.load(str(folder), run, CASES)
    assert "\n" not in str(e.value) and expect in str(e.value), str(e.value)


def test_the_same_frames_are_compared_case_by_case_and_a_case_whose_frames_differ_set_apart(tmp_path):
    d = earlier(tmp_path, [row(), row(cal="no", identified=50), row(shape="egg", readable=80),
                           row(shape="box")])  # the box: not a case of this run
    base, rows = da.load(str(d), RUN, CASES)
    assert base == RUN and set(rows) == CASES
    now = [row(identified=95, wrong=1), row(cal="no", identified=50), row(shape="egg", readable=81)]
    same, differ = da.compare(now, rows)
    assert differ == [("tuning", "egg", "grey", "yes", "other frames")]
    ham = next(c for c in same if c["calibration"] == "yes")
    assert (ham["identified_before"], ham["identified_after"], ham["change_points"]) == (90, 95, 5.0)
    assert (ham["wrong_ids_before"], ham["wrong_ids_after"]) == (0, 1)
    text = da.markdown(same, differ, base, {**RUN, "decoder_option": ["growth.faintest=0"]}, str(d))
    assert "| tuning | yes | 90 → 95 | +5.556 % | 0 → 1 |" in text, text
    assert "1 cases unchanged" in text and "not the same frames (1): tuning egg grey yes." in text
    # a case of this run the earlier one did not sweep is named, not compared
    same, differ = da.compare(now + [row(shape="cone")], rows)
    assert differ[-1] == ("tuning", "cone", "grey", "yes", "not in it")
    assert "Not compared, not in the earlier run (1): tuning cone grey yes." in da.markdown(same, differ, base, RUN, str(d))
    assert "--decoder-option growth.faintest=0` against `bin/decode-heldout --poses 2 --seed 1`" in text


@pytest.mark.parametrize("setting, value", [("poses", 3), ("seed", 2), ("pattern", "servo/pattern/data/x.txt")])
def test_another_draw_or_pattern_is_refused(tmp_path, setting, value):
    refused(earlier(tmp_path, [row()], {**RUN, setting: value}), f"its run had {setting}")


def test_what_is_no_earlier_run_is_refused_in_one_line(tmp_path):
    refused(tmp_path / "none", "not a folder")
    d = earlier(tmp_path, [row()])
    (d / "run.json").unlink()
    refused(d, "run.json: missing")
    os.symlink("/etc/hostname", d / "run.json")
    refused(d, "run.json: not a regular file")
    (d / "run.json").unlink()
    (d / "run.json").write_text('{"poses": true}')
    refused(d, "'poses' missing or not a whole number")
    (d / "run.json").write_text("[1, 2]")
    refused(d, "not a JSON object")
    (d / "run.json").write_text("[" * 20000 + "]" * 20000)  # deeper than Python's stack
    refused(d, "run.json: not JSON")
    (d / "run.json").write_text(json.dumps(RUN))
    os.mkfifo(d / "decode.csv.fifo")
    (d / "decode.csv").unlink()
    os.rename(d / "decode.csv.fifo", d / "decode.csv")
    refused(d, "decode.csv: not a regular file")  # and not opened: a FIFO would block a read


@pytest.mark.parametrize("change, expect", [
    (lambda rows: rows[0].update(readable="12x"), "line 2: readable is not a whole number"),
    (lambda rows: rows[0].update(identified="-5"), "line 2: identified is not a whole number"),
    (lambda rows: rows[0].update(poses=400), "swept at '400' poses where run.json says 2"),
    (lambda rows: rows[0].update(shape="../ham"), "line 2: not a case of decode-heldout"),
    (lambda rows: rows.append(dict(rows[0])), "line 3: the case tuning ham grey yes a second time"),
])
def test_a_table_that_is_not_one_is_refused_naming_its_line(tmp_path, change, expect):
    rows = [row()]
    change(rows)
    refused(earlier(tmp_path, rows), expect)


def test_a_table_without_a_count_or_too_large_or_sharing_no_case_is_refused(tmp_path):
    d = earlier(tmp_path, [row(shape="box")])
    refused(d, "no case of this run is in its decode.csv")
    with open(d / "decode.csv", "a") as f:
        f.write("tuning,ham,grey,yes\n")  # a row short of its counts
    refused(d, "line 3: swept at '' poses")
    (d / "decode.csv").write_bytes(b"set,shape\n\0\n")
    refused(d, "decode.csv:")
    (d / "decode.csv").write_text(",".join(COLUMNS) + "\n" + "x" * 200000 + "\n")  # a field past csv's limit
    refused(d, "decode.csv: not a table")
    (d / "decode.csv").write_text("set,shape,condition,calibration,poses,readable\n")
    refused(d, "decode.csv: no column identified")
    (d / "decode.csv").write_bytes(b"a" * (da.MAX_CSV_BYTES + 1))
    refused(d, f"decode.csv: more than {da.MAX_CSV_BYTES} bytes")


def wrong_ids(root, key, rows):
    folder = da.case_folder(str(root), key)
    os.makedirs(folder)
    with open(os.path.join(folder, "wrong_ids.csv"), "w") as f:
        f.write("pose,row,col,u,v,nearest_visible_row,nearest_visible_col,nearest_visible_px,named_visible,named_px,step\n")
        for pose, r, c, nr, nc in rows:
            f.write(f"{pose},{r},{c},1.0,2.0,{nr},{nc},0.5,1,6.0,6\n")


def test_which_wrong_ids_a_change_took_out_and_which_it_added_are_listed(tmp_path):
    ham, egg = ("tuning", "ham", "grey", "yes"), ("tuning", "egg", "grey", "yes")
    wrong_ids(tmp_path / "base", ham, [(3, 9, 11, 10, 14), (7, 1, 2, 3, 4)])
    wrong_ids(tmp_path / "now", ham, [(7, 1, 2, 3, 4), (8, 5, 5, 6, 6)])
    wrong_ids(tmp_path / "base", egg, [(1, 2, 3, 4, 5)])
    os.makedirs(da.case_folder(str(tmp_path / "now"), egg))
    (tmp_path / "now" / "tuning" / "egg" / "grey" / "egg_grey_cal" / "wrong_ids.csv").write_text("pose,row\n1,2\n")
    same = [{**dict(zip(da.KEY, key)), "wrong_ids_before": 2, "wrong_ids_after": 2} for key in (ham, egg)]
    gone, new, unread = da.wrong_id_changes(same, str(tmp_path / "now"), str(tmp_path / "base"))
    assert gone == [(ham, (3, 9, 11), (10, 14))] and new == [(ham, (8, 5, 5), (6, 6))]
    assert unread == [(egg, "this run's wrong_ids.csv: not a table of wrong ids")]
    text = da.markdown([], [], RUN, RUN, "base", (gone, new, unread))
    assert "| tuning | ham | grey | yes | 3 | (9, 11) | (10, 14) |" in text
    assert "**Wrong ids new** (1)" in text and "The wrong ids of tuning egg grey yes not compared" in text
