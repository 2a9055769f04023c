"""What a decoder change did, case by case: `bin/decode-heldout --against DIR` compares its run
with an earlier one, DIR, on the same frames (imported by decode-heldout, not run).

Two runs see the same frames when they drew the same poses (--poses, --seed) of the same scenes
casting the same pattern; what may differ is the decoder (a build, --decoder-option,
--fitted-lines, --taught-points, --white-frame). Each run writes run.json, its settings; the
earlier run's settings and decode.csv are read as untrusted files: regular files only, bounded in
bytes, every field checked, and a run whose frames differ is refused before anything is swept.
"""
import csv
import io
import json
import os
import re
import stat

MAX_CSV_BYTES = 1 << 20   # 192 cases take 60 kB
MAX_JSON_BYTES = 64 << 10
SAME_FRAMES = ("poses", "seed", "pattern")
# the counts compared (decode.csv's columns)
COUNTS = ("readable", "identified", "wrong_ids", "mislocated", "partial", "to_law_partial", "to_law_wrong")
KEY = ("set", "shape", "condition", "calibration")
SETTINGS = {"poses": int, "seed": int, "pattern": str, "decoder_option": list, "fitted_lines": bool,
            "taught_points": bool, "white_frame": bool}

KINDS = {int: "a whole number", str: "text", list: "a list", bool: "true or false"}


class Refused(Exception):
    """A baseline that cannot be compared with this run; the message is one line."""


def settings_of(opts, top):
    """This run's settings, as run.json holds them."""
    return {"poses": opts.poses, "seed": opts.seed,
            "pattern": os.path.relpath(opts.pattern, top) if opts.pattern else "",
            "decoder_option": list(opts.decoder_option), "fitted_lines": bool(opts.fitted_lines),
            "taught_points": bool(opts.taught_points), "white_frame": bool(opts.white_frame)}


def command_of(s):
    """The decode-heldout options a run's settings stand for (the sets and conditions aside)."""
    words = [f"--poses {s['poses']}", f"--seed {s['seed']}"]
    words += [f"--pattern {s['pattern']}"] if s["pattern"] else []
    words += [f"--decoder-option {a}" for a in s["decoder_option"]]
    words += [f"--{k.replace('_', '-')}" for k in ("fitted_lines", "taught_points", "white_frame") if s[k]]
    return "bin/decode-heldout " + " ".join(words)


def _read_regular(path, limit, what):
    """The text of a regular file of at most `limit` bytes; Refused naming `what` otherwise."""
    try:
        st = os.lstat(path)
    except OSError:
        raise Refused(f"{what}: missing") from None
    if not stat.S_ISREG(st.st_mode):
        raise Refused(f"{what}: not a regular file")
    if st.st_size > limit:
        raise Refused(f"{what}: more than {limit} bytes")
    fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    with os.fdopen(fd, "rb") as f:
        data = f.read(limit + 1)
    if len(data) > limit:
        raise Refused(f"{what}: more than {limit} bytes")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise Refused(f"{what}: not UTF-8 text") from None


def _settings(folder):
    text = _read_regular(os.path.join(folder, "run.json"), MAX_JSON_BYTES, "run.json")
    try:
        s = json.loads(text)
    except (ValueError, RecursionError) as e:  # (nested deeper than Python's stack: no run.json we wrote)
        raise Refused(f"run.json: not JSON ({str(e).splitlines()[0]})") from None
    if not isinstance(s, dict):
        raise Refused("run.json: not a JSON object")
    for k, kind in SETTINGS.items():
        v = s.get(k)
        if not isinstance(v, kind) or (kind is int and isinstance(v, bool)):
            raise Refused(f"run.json: '{k}' missing or not {KINDS[kind]}")
        if kind is list and not all(isinstance(a, str) and len(a) <= 200 for a in v):
            raise Refused(f"run.json: '{k}' holds something other than NAME=VALUE text")
        if kind is str and len(v) > 4096:
            raise Refused(f"run.json: '{k}' longer than 4096 characters")
    return {k: s[k] for k in SETTINGS}


def _table(path, name, columns, lacking=None):
    """A CSV file's rows as (line, {column: text}), every named column there; a row short of a
    column reads it as ''. Refused when the file is not such a table (csv's own errors too: a NUL,
    a field past its limit)."""
    text = _read_regular(path, MAX_CSV_BYTES, name)
    try:
        reader = csv.DictReader(io.StringIO(text, newline=""))
        missing = [c for c in columns if c not in (reader.fieldnames or [])]
        if missing:
            raise Refused(f"{name}: {lacking or f'no column {missing[0]}'}")
        return [(n, {c: r[c] or "" for c in columns}) for n, r in enumerate(reader, start=2)]
    except csv.Error as e:
        raise Refused(f"{name}: not a table ({e})") from None


def _rows(folder, poses):
    """decode.csv's cases, each swept at `poses` (run.json's: a table from another run is refused)."""
    table = _table(os.path.join(folder, "decode.csv"), "decode.csv", KEY + ("poses",) + COUNTS)
    rows = {}
    for n, r in table:
        key = tuple(r[c] for c in KEY)
        if not (key[0] in ("tuning", "heldout") and re.fullmatch(r"[a-z_]{1,40}", key[1]) and
                re.fullmatch(r"[a-z]{1,20}", key[2]) and key[3] in ("yes", "no")):
            raise Refused(f"decode.csv: line {n}: not a case of decode-heldout")
        if r["poses"] != str(poses):
            raise Refused(f"decode.csv: line {n}: swept at {r['poses'][:20]!r} poses where run.json says {poses}")
        counts = {}
        for c in COUNTS:
            if not re.fullmatch(r"[0-9]{1,12}", r[c]):
                raise Refused(f"decode.csv: line {n}: {c} is not a whole number")
            counts[c] = int(r[c])
        if key in rows:
            raise Refused(f"decode.csv: line {n}: the case {' '.join(key)} a second time")
        rows[key] = counts
    return rows


def load(folder, run, cases):
    """The earlier run in `folder`: its settings and its rows of the cases this run will sweep.
    Refused (one line, naming the file) unless it saw the same frames and shares a case."""
    if not os.path.isdir(folder) or os.path.islink(folder):
        raise Refused("not a folder")
    base = _settings(folder)
    for k in SAME_FRAMES:
        if base[k] != run[k]:
            raise Refused(f"its run had {k} {base[k]!r} and this one {run[k]!r}: not the same frames")
    rows = _rows(folder, base["poses"])
    shared = {k: v for k, v in rows.items() if k in cases}
    if not shared:
        raise Refused("no case of this run is in its decode.csv")
    return base, shared


def compare(rows, base):
    """Per case both runs swept: the counts before and after. The cases not compared are returned
    apart, each with why: not in the earlier run, or its readable spots differ (other frames:
    another simulator or scene)."""
    same, differ = [], []
    for r in rows:
        key = tuple(r[c] for c in KEY)
        if key not in base:
            differ.append(key + ("not in it",))
            continue
        b = base[key]
        if b["readable"] != int(r["readable"]):
            differ.append(key + ("other frames",))
            continue
        same.append({**{c: r[c] for c in KEY}, "readable": b["readable"],
                     **{f"{c}_before": b[c] for c in COUNTS[1:]},
                     **{f"{c}_after": int(r[c]) for c in COUNTS[1:]},
                     "change_points": round(100 * (int(r["identified"]) - b["identified"]) / (b["readable"] or 1), 3)})
    return same, differ


def case_folder(root, key):
    """Where decode-heldout's sweep of a case writes its tables (sweep.csv, wrong_ids.csv): decode-heldout
    sweeps into it, and the comparison reads the earlier run's from it."""
    set_name, shape, condition, cal = key
    return os.path.join(root, set_name, shape, condition, f"{shape}_{condition}" + ("_cal" if cal == "yes" else ""))


def _wrong_ids(path):
    """A sweep's wrong ids as {(pose, row, col): (nearest spot's row, col)}; Refused if the
    table is not one."""
    cols = ("pose", "row", "col", "nearest_visible_row", "nearest_visible_col")
    out = {}
    for n, r in _table(path, "wrong_ids.csv", cols, lacking="not a table of wrong ids"):
        if not all(re.fullmatch(r"-?[0-9]{1,9}", r[c]) for c in cols):
            raise Refused(f"wrong_ids.csv: line {n}: not whole numbers")
        out[(int(r["pose"]), int(r["row"]), int(r["col"]))] = (int(r["nearest_visible_row"]), int(r["nearest_visible_col"]))
    return out


def wrong_id_changes(same, out_dir, base_dir):
    """Per case whose wrong ids differ in number or in which: those taken out and those new, each
    (key, pose, id, the spot it lay on); and the cases whose tables could not be read, with why."""
    gone, new, unread = [], [], []
    for c in same:
        key = tuple(c[k] for k in KEY)
        if c["wrong_ids_before"] == 0 and c["wrong_ids_after"] == 0:
            continue
        try:
            before = _wrong_ids(os.path.join(case_folder(base_dir, key), "wrong_ids.csv"))
        except Refused as e:
            unread.append((key, f"the earlier run's {e}"))
            continue
        try:
            after = _wrong_ids(os.path.join(case_folder(out_dir, key), "wrong_ids.csv"))
        except Refused as e:
            unread.append((key, f"this run's {e}"))
            continue
        gone += [(key, k, before[k]) for k in sorted(set(before) - set(after))]
        new += [(key, k, after[k]) for k in sorted(set(after) - set(before))]
    return gone, new, unread


def _wrong_table(title, items):
    if not items:
        return ""
    out = [f"\n**{title}** ({len(items)})\n\n| set | shape | condition | calibration | pose | id named | "
           "the spot it lay on |\n|---|---|---|---|---|---|---|\n"]
    for key, (pose, row, col), spot in items:
        out.append(f"| {' | '.join(key)} | {pose} | ({row}, {col}) | ({spot[0]}, {spot[1]}) |\n")
    return "".join(out)


def _n(x):
    return f"{x:,}".replace(",", " ")


def markdown(same, differ, base, run, folder, changes=((), (), ())):
    out = [f"`{command_of(run)}` against `{command_of(base)}` (`{folder}`): the same frames, {len(same)} cases\n",
           "\n| set | calibration | identified before → after | change | wrong ids | mislocated | spills "
           "| spills reaching the law | wrong ids reaching the law |\n|---|---|---|---|---|---|---|---|---|\n"]
    for set_name in dict.fromkeys(c["set"] for c in same):
        for cal in ("yes", "no"):
            cs = [c for c in same if c["set"] == set_name and c["calibration"] == cal]
            if not cs:
                continue
            t = {k: sum(c[k] for c in cs) for k in cs[0] if k.endswith(("_before", "_after"))}
            pct = 100 * (t["identified_after"] - t["identified_before"]) / (t["identified_before"] or 1)
            pair = lambda k: f"{_n(t[k + '_before'])} → {_n(t[k + '_after'])}"
            out.append(f"| {set_name} | {cal} | {pair('identified')} | {pct:+.3f} % | {pair('wrong_ids')} | "
                       f"{pair('mislocated')} | {pair('partial')} | {pair('to_law_partial')} | {pair('to_law_wrong')} |\n")
    changed = sorted((c for c in same if any(c[f"{k}_before"] != c[f"{k}_after"] for k in COUNTS[1:])),
                     key=lambda c: c["change_points"])
    if changed:
        out.append("\n**The cases that changed** (the largest loss first; points of the case's readable spots)\n"
                   "\n| set | shape | condition | calibration | identified | change (points) | wrong ids "
                   "| spills reaching the law |\n|---|---|---|---|---|---|---|---|\n")
        for c in changed:
            out.append(f"| {c['set']} | {c['shape']} | {c['condition']} | {c['calibration']} | "
                       f"{_n(c['identified_before'])} → {_n(c['identified_after'])} | {c['change_points']:+.2f} | "
                       f"{c['wrong_ids_before']} → {c['wrong_ids_after']} | "
                       f"{c['to_law_partial_before']} → {c['to_law_partial_after']} |\n")
    gone, new, unread = changes
    out.append(_wrong_table("Wrong ids taken out", gone))
    out.append(_wrong_table("Wrong ids new", new))
    for key, why in unread:
        out.append(f"\nThe wrong ids of {' '.join(key)} not compared: {why}.\n")
    out.append(f"\n{len(same) - len(changed)} cases unchanged, count for count.\n")
    for why, what in (("not in it", "not in the earlier run"),
                      ("other frames", "their readable spots differ, not the same frames")):
        cases = [" ".join(k[:4]) for k in differ if k[4] == why]
        if cases:
            out.append(f"\nNot compared, {what} ({len(cases)}): {', '.join(cases)}.\n")
    return "".join(out)


def plot(same, path, title, save, plt):
    """Per set and calibration, the change of each case that changed (points), the largest first;
    a case's wrong ids before → after in its label, in red, where they changed."""
    panels = [(s, cal) for s in dict.fromkeys(c["set"] for c in same) for cal in ("yes", "no")
              if any(c["set"] == s and c["calibration"] == cal for c in same)]
    changed = {p: sorted((c for c in same if (c["set"], c["calibration"]) == p and
                          (c["change_points"] != 0 or c["wrong_ids_before"] != c["wrong_ids_after"])),
                         key=lambda c: -abs(c["change_points"])) for p in panels}
    shown = {p: v[:15] for p, v in changed.items()}
    rows = max([len(v) for v in shown.values()] + [4])
    fig, axes = plt.subplots(1, len(panels), figsize=(5.4 * len(panels), 0.32 * rows + 1.8), squeeze=False)
    for ax, p in zip(axes[0], panels):
        cs = shown[p]
        ys = range(len(cs))
        ax.barh(list(ys), [c["change_points"] for c in cs],
                color=["#2a8a3a" if c["change_points"] >= 0 else "#c03030" for c in cs])
        # a case whose wrong ids changed says so in its label, in red: a wrong id is worse than none
        moved = [c["wrong_ids_before"] != c["wrong_ids_after"] for c in cs]
        ax.set_yticks(list(ys), [f"{c['shape']} {c['condition']}" +
                                 (f" (wrong ids {c['wrong_ids_before']}→{c['wrong_ids_after']})" if m else "")
                                 for c, m in zip(cs, moved)], fontsize=8)
        for label, m in zip(ax.get_yticklabels(), moved):
            if m:
                label.set_color("#b00000")
        ax.invert_yaxis()
        if cs:
            ax.axvline(0, color="black", lw=0.8)
        ax.set_xlabel("change in readable spots identified (points)")
        unchanged = sum(1 for c in same if (c["set"], c["calibration"]) == p) - len(changed[p])
        largest = f"; the {len(cs)} largest of {len(changed[p])} changes" if len(changed[p]) > len(cs) else ""
        ax.set_title(f"{'held-out' if p[0] == 'heldout' else p[0]} scenes, "
                     f"{'with' if p[1] == 'yes' else 'without'} the calibration\n"
                     f"({unchanged} cases unchanged{largest})", fontsize=9)
        ax.grid(axis="x", alpha=0.3)
        if not cs:
            ax.text(0.5, 0.5, "no case changed", transform=ax.transAxes, ha="center", va="center")
            ax.set_yticks([])
            ax.set_xticks([])
    fig.suptitle(title, fontsize=10, y=0.995)
    save(fig, path, top=1 - 0.3 / (0.32 * rows + 1.8))
