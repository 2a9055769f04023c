"""Writing an output file under the rule every program of the project follows (imported by the
scripts, not run; idl/common/output_file.hpp is the C++ side): a file is written only if it is
new, or if the list `.cell-written` in its folder says that a program of this project wrote it
there. A user's own file of one of our names is refused in one line and kept; a symbolic link,
a FIFO or a folder in the file's place is never written through."""
import os
import stat
import sys

WRITTEN_LIST = ".cell-written"
MAX_LIST_BYTES = 8 << 20  # as the C++ side: bounds what a list planted in a folder makes us read


def _refuse(path, why):
    shown = "".join(c if c.isprintable() else f"\\x{ord(c):02x}" for c in str(path))  # one line, whatever the name
    sys.exit(f"{os.path.basename(sys.argv[0])}: {shown}: {why}")


def _kind(mode):
    if stat.S_ISLNK(mode):
        return "a symbolic link"
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    return "not a regular file"


def _listed(folder, name):
    """Whether the folder's list names `name` (bytes)."""
    lst = os.path.join(folder, WRITTEN_LIST)
    try:
        st = os.lstat(lst)
    except FileNotFoundError:
        return False
    if not stat.S_ISREG(st.st_mode):
        _refuse(lst, f"the list of the files written here is {_kind(st.st_mode)}; not read")
    if st.st_size > MAX_LIST_BYTES:
        _refuse(lst, f"the list of the files written here is more than {MAX_LIST_BYTES} bytes")
    fd = os.open(lst, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    with os.fdopen(fd, "rb") as f:
        return name in f.read(MAX_LIST_BYTES).split(b"\n")


def _record(folder, name):
    lst = os.path.join(folder, WRITTEN_LIST)
    if _listed(folder, name):
        return
    try:
        fd = os.open(lst, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC | os.O_NONBLOCK, 0o644)
    except OSError as e:
        _refuse(lst, f"cannot keep the list of the files written here: {e.strerror}")
    with os.fdopen(fd, "ab") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
            _refuse(lst, "the list of the files written here is not a regular file")
        f.write(name + b"\n")  # O_APPEND: one short write lands whole beside other writers'


def open_output(path, mode="w", **kwargs):
    """`path` opened for writing (emptied) under the rule above, as open() would open it."""
    name = os.fsencode(os.path.basename(path))
    if name in (b"", b".", b"..") or name == WRITTEN_LIST.encode() or b"\n" in name:
        _refuse(path, "not a name an output may have")
    folder = os.path.dirname(path) or "."
    flags = os.O_WRONLY | os.O_NOFOLLOW | os.O_CLOEXEC | os.O_NOCTTY | os.O_NONBLOCK
    created = False
    try:
        fd = os.open(path, flags | os.O_CREAT | os.O_EXCL, 0o644)
        created = True
    except FileExistsError:
        st = os.lstat(path)
        if not stat.S_ISREG(st.st_mode):
            _refuse(path, f"is {_kind(st.st_mode)}; not written through (move it away)")
        if not _listed(folder, name):
            _refuse(path, f"exists and was not written here by this project ({WRITTEN_LIST} does not list it); "
                          "not overwritten: move it away or name another folder")
        fd = os.open(path, flags)
        if os.fstat(fd).st_nlink > 1:  # a hard link: emptying ours would empty the other name's bytes
            os.close(fd)
            _refuse(path, "has other names (hard links); not written over: move it away")
        os.ftruncate(fd, 0)
    except OSError as e:
        _refuse(path, f"cannot create it: {e.strerror}")
    try:
        _record(folder, name)
    except SystemExit:
        os.close(fd)
        if created:
            os.unlink(path)  # ours, made above with O_EXCL and still empty
        raise
    os.set_blocking(fd, True)
    return os.fdopen(fd, mode, **kwargs)
