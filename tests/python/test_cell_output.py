"""bin/cell_output.py, the plot scripts' side of the output rule (idl/common/output_file.hpp is
the C++ side, tests/unit/common its tests): a new file is written and listed, a listed one is
written over, and a user's file, a link, a hard link or a FIFO in an output's place is refused in
one line and left as it was."""
import os
import sys

import pytest

sys.path.insert(0, os.path.join(os.environ["CELL_SOURCE_DIR"], "bin"))
from cell_output import WRITTEN_LIST, open_output  # noqa: E402


def refused(path, expect):
    with pytest.raises(SystemExit) as e:
        open_output(str(path), "w")
    message = str(e.value.code)
    assert "\n" not in message and str(path) in message and expect in message, message


def test_a_new_file_is_listed_and_the_next_run_writes_over_it(tmp_path):
    f = tmp_path / "velocities.png"
    with open_output(str(f), "w") as out:
        out.write("first run, longer\n")
    with open_output(str(f), "w") as out:
        out.write("2\n")
    assert f.read_text() == "2\n"
    assert (tmp_path / WRITTEN_LIST).read_text() == "velocities.png\n"


def test_a_users_file_a_link_and_a_hard_link_are_refused_and_kept(tmp_path):
    victim = tmp_path / "victim"
    victim.write_text("precious\n")
    mine = tmp_path / "fig4.png"
    mine.write_text("my figure\n")
    refused(mine, "exists and was not written here")
    assert mine.read_text() == "my figure\n"
    (tmp_path / WRITTEN_LIST).write_text("link.png\nhard.png\n")  # listed, and still refused
    os.symlink(victim, tmp_path / "link.png")
    refused(tmp_path / "link.png", "is a symbolic link")
    os.link(victim, tmp_path / "hard.png")
    refused(tmp_path / "hard.png", "hard links")
    assert victim.read_text() == "precious\n"


def test_a_fifo_is_refused_and_a_list_that_is_a_link_takes_nothing(tmp_path):
    os.mkfifo(tmp_path / "fifo.png")
    refused(tmp_path / "fifo.png", "a FIFO")
    (tmp_path / "elsewhere").write_text("")
    os.symlink(tmp_path / "elsewhere", tmp_path / WRITTEN_LIST)
    with pytest.raises(SystemExit):
        open_output(str(tmp_path / "new.png"), "w")
    assert not (tmp_path / "new.png").exists()  # the file it had made is taken back
    assert (tmp_path / "elsewhere").read_text() == ""
