#!/usr/bin/python3
"""Issue 42: the compiler enforces the picture. Each case compiles a one-line probe with the
very flags the build gives a source file of a library (compile_commands.json): a header of a
library it links is found, a header across an arrow the build does not draw is a missing file.

    forbidden_include_test.py BUILD/compile_commands.json SOURCE_ROOT
"""
import json
import os
import shlex
import subprocess
import sys
import tempfile

# (a source of the library whose view is probed, the header it includes, found or not)
CASES = [
    ("servo/control/control_law.cpp", "servo/calibration/camera_intrinsics.hpp", True),
    ("servo/control/control_law.cpp", "sim/render/renderer.hpp", False),     # the law never sees the renderer
    ("servo/control/control_law.cpp", "servo/vision/spot_decoder.hpp", False),  # nor the decoder
    ("servo/vision/spot_decoder.cpp", "servo/control/control_law.hpp", False),  # the decoder, not the law
    ("sim/service/sim_service.cpp", "sim/render/renderer.hpp", True),
    ("sim/service/sim_service.cpp", "sim/loop/in_memory_loop.hpp", False),  # the service, not the meeting place
    ("sim/service/sim_service.cpp", "servo/pipeline/servo_pipeline.hpp", False),
    ("sim/session/cell_state_machine.cpp", "sim/arm/arm_scenario.hpp", False),  # the session: no URDF, KDL, Bullet
    ("sim/render/renderer.cpp", "servo/vision/spot_decoder.hpp", False),  # the simulator never decodes
    ("idl/mcap/mcap_reader.cpp", "common/regular_file.hpp", True),
    ("idl/mcap/mcap_reader.cpp", "servo/pattern/marray.hpp", False),  # the bottom never includes up
    ("sim/loop/in_memory_loop.cpp", "common/plot_script.hpp", False),  # the loop writes no files, spawns no plots
]


def probe_command(entry, probe):
    """The entry's compile command, compiling `probe` for syntax only."""
    args = entry["arguments"] if "arguments" in entry else shlex.split(entry["command"])
    out, skip = [], 0
    for a in args:
        if skip:
            skip -= 1
            continue
        if a in ("-o", "-MT", "-MF", "-c"):
            skip = 1
            continue
        if a in ("-MD", "-MMD"):
            continue
        out.append(a)
    return out + ["-fsyntax-only", probe]


def main():
    db_path, root = sys.argv[1], os.path.realpath(sys.argv[2])
    db = {os.path.realpath(os.path.join(e["directory"], e["file"])): e for e in json.load(open(db_path))}
    failures = 0
    with tempfile.TemporaryDirectory() as tmp:
        for source, header, found in CASES:
            entry = db.get(os.path.join(root, source))
            if entry is None:
                print(f"FAIL: {source} is not in {db_path}")
                failures += 1
                continue
            probe = os.path.join(tmp, "probe.cpp")
            with open(probe, "w") as f:
                f.write(f'#include "{header}"\n')
            done = subprocess.run(probe_command(entry, probe), cwd=entry["directory"], capture_output=True, text=True)
            missing = f"{header}: No such file or directory" in done.stderr
            if found and done.returncode != 0:
                print(f"FAIL: {source}'s library should see {header}:\n{done.stderr.strip()[:2000]}")
                failures += 1
            elif not found and not (done.returncode != 0 and missing):
                print(f"FAIL: {source}'s library includes {header} across a forbidden arrow, and it compiled "
                      f"(exit {done.returncode})\n{done.stderr.strip()[:2000]}")
                failures += 1
            else:
                print(f"ok: {source}: {header} {'found' if found else 'refused by the compiler'}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
