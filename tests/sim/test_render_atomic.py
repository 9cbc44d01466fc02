"""The GIF / MP4 writers and `save_image` write all or nothing: real encoding, frames or writes that fail
partway (an error from the frame source, Ctrl-C, a file system that refuses more bytes), and what is left in
the folder afterwards (no GL needed)."""

from __future__ import annotations

import errno
import os
import stat
import subprocess
import sys
import textwrap
from collections.abc import Callable, Iterator
from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest
from PIL import Image as PILImage
from servoface.sim.render import video
from servoface.sim.render.atomic import PARTIAL, atomic_output
from servoface.sim.render.images import save_image
from servoface.sim.render.video import write_gif, write_mp4

Writer = Callable[..., int]
CLIPS = [pytest.param(write_mp4, ".mp4", id="mp4"), pytest.param(write_gif, ".gif", id="gif")]


def _frames(n: int, h: int = 31, w: int = 41, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (h, w, 3), dtype=np.uint8) for _ in range(n)]


def _failing(frames: list[np.ndarray], at: int, error: BaseException) -> Iterator[np.ndarray]:
    """The frames, but raising ``error`` when frame ``at`` is asked for (a render that fails partway)."""
    for i, frame in enumerate(frames):
        if i == at:
            raise error
        yield frame


def _decoded(path: Path) -> tuple[int, tuple[int, int]]:
    """(frame count, (height, width)) of a GIF or MP4, read back by a decoder."""
    if path.suffix == ".gif":
        with PILImage.open(path) as im:
            return im.n_frames, (im.size[1], im.size[0])
    reader = imageio.get_reader(str(path))
    try:
        return reader.count_frames(), reader.get_data(0).shape[:2]
    finally:
        reader.close()


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@pytest.mark.parametrize(("write", "suffix"), CLIPS)
@pytest.mark.parametrize("error", [RuntimeError("render failed"), KeyboardInterrupt()], ids=["error", "ctrl-c"])
def test_a_failed_clip_leaves_no_file(write: Writer, suffix: str, error: BaseException, tmp_path: Path) -> None:
    target = tmp_path / f"clip{suffix}"
    with pytest.raises(type(error)) as caught:
        write(_failing(_frames(10), 6, error), target)
    assert caught.value is error  # re-raised as it came, not wrapped or replaced by a close error
    assert list(tmp_path.iterdir()) == []  # neither the target nor a temporary


@pytest.mark.parametrize(("write", "suffix"), CLIPS)
def test_a_failed_clip_keeps_the_file_already_there(write: Writer, suffix: str, tmp_path: Path) -> None:
    target = tmp_path / f"clip{suffix}"
    assert write(_frames(4, 20, 24, seed=1), target) == 4
    target.chmod(0o640)
    before, inode = target.read_bytes(), target.stat().st_ino
    with pytest.raises(RuntimeError, match="render failed"):
        write(_failing(_frames(12), 9, RuntimeError("render failed")), target)
    with pytest.raises(ValueError, match="differs from the first frame"):  # a bad frame is a failure too
        write([*_frames(3), *_frames(1, 20, 24)], target)
    assert target.read_bytes() == before and target.stat().st_ino == inode
    assert stat.S_IMODE(target.stat().st_mode) == 0o640
    assert [p.name for p in tmp_path.iterdir()] == [target.name]
    assert _decoded(target) == (4, (20, 24))


@pytest.mark.parametrize(("write", "suffix"), CLIPS)
def test_a_finished_clip_replaces_the_file_and_decodes(write: Writer, suffix: str, tmp_path: Path) -> None:
    """Same frames, same result as a direct write: every frame, the padded size for MP4; a replaced file
    keeps its mode, a new one gets what the umask makes of 0o666 (as ``open`` gives), not mkstemp's 0o600."""
    fresh, target = tmp_path / f"fresh{suffix}", tmp_path / f"clip{suffix}"
    assert write(_frames(12), fresh, fps=20) == 12
    assert stat.S_IMODE(fresh.stat().st_mode) == 0o666 & ~_umask()
    target.write_bytes(b"an older result")
    target.chmod(0o640)
    assert write(_frames(12), target, fps=20) == 12
    assert _decoded(target) == (12, (32, 42) if suffix == ".mp4" else (31, 41))  # mp4: even sides
    assert target.read_bytes() == fresh.read_bytes()  # the temporary's name is not in the file
    assert stat.S_IMODE(target.stat().st_mode) == 0o640
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([fresh.name, target.name])


def test_the_gif_keeps_every_frame_exactly(tmp_path: Path) -> None:
    frames = [np.full((8, 10, 3), v, np.uint8) for v in (0, 90, 180, 250)]  # 4 colours: the palette is exact
    assert write_gif(frames, tmp_path / "c.gif") == 4
    with PILImage.open(tmp_path / "c.gif") as im:
        for i, frame in enumerate(frames):
            im.seek(i)
            assert np.array_equal(np.asarray(im.convert("RGB")), frame)


def test_a_still_is_written_exactly_and_replaced_only_when_complete(tmp_path: Path) -> None:
    img = _frames(1, 40, 50)[0]
    target = tmp_path / "face.png"
    target.write_bytes(b"an older still")
    save_image(img, target)
    with PILImage.open(target) as im:
        assert np.array_equal(np.asarray(im), img)
    before = target.read_bytes()
    with pytest.raises(ValueError, match="uint8"):
        save_image(np.zeros((4, 4, 3)), target)
    with pytest.raises(ValueError, match="unknown file extension"):  # Pillow's own message, as before
        save_image(img, tmp_path / "face.xyz")
    assert target.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == [target.name]


@pytest.mark.parametrize("suffix", [".mp4", ".gif", ".png"])
def test_a_symlink_is_written_through(suffix: str, tmp_path: Path) -> None:
    """The file a symlink points at is replaced and the link stays; the link's suffix picks the format even
    when the file it points at has none."""
    real = tmp_path / "store" / "blob"
    real.parent.mkdir()
    real.write_bytes(b"old")
    link = tmp_path / f"out{suffix}"
    link.symlink_to(real)
    if suffix == ".png":
        save_image(_frames(1)[0], link)
    else:
        (write_mp4 if suffix == ".mp4" else write_gif)(_frames(5), link)
    assert link.is_symlink() and link.resolve() == real
    if suffix == ".png":
        with PILImage.open(real) as im:
            assert im.format == "PNG"
    else:
        copy = tmp_path / f"copy{suffix}"  # decoders pick the reader by the suffix too
        copy.write_bytes(real.read_bytes())
        assert _decoded(copy)[0] == 5
    assert [p.name for p in real.parent.iterdir()] == ["blob"]


@pytest.mark.parametrize(("write", "suffix"), CLIPS)
def test_bad_targets_are_refused_before_any_frame(write: Writer, suffix: str, tmp_path: Path) -> None:
    """A missing folder or a folder as the target fail before the frame source is touched, naming the
    target (not the temporary), as ``open(target)`` would."""
    asked: list[int] = []

    def frames() -> Iterator[np.ndarray]:
        asked.append(1)
        yield from _frames(2)

    missing = tmp_path / "nowhere" / f"clip{suffix}"
    with pytest.raises(FileNotFoundError) as caught:
        write(frames(), missing)
    assert caught.value.filename == os.fspath(missing) and PARTIAL not in str(caught.value)
    folder = tmp_path / f"folder{suffix}"
    folder.mkdir()
    with pytest.raises(IsADirectoryError) as caught_dir:
        write(frames(), folder)
    assert caught_dir.value.filename == os.fspath(folder)
    assert asked == [] and list(folder.iterdir()) == [] and [p.name for p in tmp_path.iterdir()] == [folder.name]


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root may write a read-only file")
def test_a_read_only_file_is_refused_not_replaced(tmp_path: Path) -> None:
    target = tmp_path / "clip.gif"
    target.write_bytes(b"protected")
    target.chmod(0o444)
    with pytest.raises(PermissionError):
        write_gif(_frames(2), target)
    assert target.read_bytes() == b"protected" and [p.name for p in tmp_path.iterdir()] == [target.name]


def test_an_os_error_while_writing_names_the_target(tmp_path: Path) -> None:
    target = tmp_path / "x.png"
    with pytest.raises(OSError) as info, atomic_output(target) as tmp:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp))
    assert str(info.value) == f"[Errno {errno.ENOSPC}] {os.strerror(errno.ENOSPC)}: {str(target)!r}"
    with pytest.raises(OSError, match=r"^disk$"), atomic_output(target):
        raise OSError("disk")  # a message of its own is kept as it is
    assert list(tmp_path.iterdir()) == []


def test_atomic_output_cleans_up_on_any_exception(tmp_path: Path) -> None:
    target = tmp_path / "x.png"
    for error in (OSError("disk"), KeyboardInterrupt(), SystemExit(3)):
        with pytest.raises(type(error)), atomic_output(target) as tmp:
            assert tmp.parent == tmp_path and tmp.name.startswith(".x.png" + PARTIAL) and tmp.suffix == ".png"
            tmp.write_bytes(b"half")
            raise error
    assert list(tmp_path.iterdir()) == []
    long_name = tmp_path / ("n" * 250 + ".png")  # the temporary's name stays under the 255-byte limit
    with atomic_output(long_name) as tmp:
        tmp.write_bytes(b"done")
    assert long_name.read_bytes() == b"done" and list(tmp_path.iterdir()) == [long_name]


def test_an_unfinished_mp4_is_not_taken_for_a_result(tmp_path: Path) -> None:
    """imageio-ffmpeg does not say how ffmpeg exited, so the writer reads back what ffmpeg wrote: a file cut
    short (no index) counts as unreadable."""
    whole = tmp_path / "whole.mp4"
    assert write_mp4(_frames(10), whole) == 10
    assert video._encoded_frames(whole) == 10
    cut = tmp_path / "cut.mp4"
    cut.write_bytes(whole.read_bytes()[: whole.stat().st_size // 2])
    assert video._encoded_frames(cut) is None


_FULL_DISK = textwrap.dedent(
    """
    import os, resource, signal, sys
    import numpy as np
    from servoface.sim.render.images import save_image
    from servoface.sim.render.video import write_gif, write_mp4

    folder = sys.argv[1]
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG instead
    resource.setrlimit(resource.RLIMIT_FSIZE, (4000, 4000))  # ffmpeg inherits it
    frames = [np.random.default_rng(k).integers(0, 256, (64, 80, 3), dtype=np.uint8) for k in range(20)]
    for name, write in (
        ("clip.mp4", lambda p: write_mp4(frames, p)),
        ("clip.gif", lambda p: write_gif(frames, p)),
        ("still.png", lambda p: save_image(frames[0], p)),
        ("new.mp4", lambda p: write_mp4(frames, p)),
        ("new.png", lambda p: save_image(frames[0], p)),
    ):
        try:
            write(os.path.join(folder, name))
        except OSError as err:
            print(name, "OSError", str(err).splitlines()[0])
        else:
            print(name, "written")
    """
)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="needs RLIMIT_FSIZE and SIGXFSZ (Linux)")
def test_a_write_the_file_system_refuses_partway_leaves_the_old_file(tmp_path: Path) -> None:
    """Real encoders writing into a file system that stops taking bytes after 4000 (as a full disk would):
    Pillow fails mid-file; ffmpeg fails while the writer is closed, which imageio-ffmpeg does not report.
    Before, each left a 4000-byte truncated file at the target, the MP4 without any error."""
    for name in ("clip.mp4", "clip.gif", "still.png"):
        (tmp_path / name).write_bytes(b"an older result")
    run = subprocess.run(
        [sys.executable, "-c", _FULL_DISK, str(tmp_path)], capture_output=True, text=True, timeout=300, check=False
    )
    assert run.returncode == 0, run.stderr
    lines = dict(line.split(" ", 1) for line in run.stdout.splitlines())
    assert set(lines) == {"clip.mp4", "clip.gif", "still.png", "new.mp4", "new.png"}
    assert all(v.startswith("OSError") for v in lines.values()), lines
    for name in ("clip.gif", "still.png", "new.png"):  # the file asked for, not the temporary (nor nothing)
        assert lines[name] == f"OSError [Errno 27] File too large: {str(tmp_path / name)!r}", lines[name]
    assert "ffmpeg did not finish the video (20 frames given" in lines["clip.mp4"] and "clip.mp4" in lines["clip.mp4"]
    assert "a full disk or a file size limit" in lines["clip.mp4"]
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == dict.fromkeys(
        ("clip.mp4", "clip.gif", "still.png"), b"an older result"
    )


def _killed_writer(target: Path) -> Path:
    """Run a process that starts writing ``target`` and is SIGKILLed partway; returns the temporary it left."""
    before = set(target.parent.iterdir())
    code = textwrap.dedent(
        f"""
        import os, signal, sys
        from servoface.sim.render.atomic import atomic_output
        with atomic_output({str(target)!r}) as tmp:
            tmp.write_bytes(b"half a clip")
            os.kill(os.getpid(), signal.SIGKILL)
        """
    )
    done = subprocess.run([sys.executable, "-c", code], check=False)
    assert done.returncode == -9
    left = [p for p in set(target.parent.iterdir()) - before if p.name.startswith(f".{target.name}{PARTIAL}")]
    assert len(left) == 1, left
    return left[0]


def _age(path: Path, seconds: float) -> None:
    then = path.stat().st_mtime - seconds
    os.utime(path, (then, then))


def test_the_next_write_removes_what_a_killed_writer_left(tmp_path: Path) -> None:
    from servoface.sim.render.atomic import STALE_S

    target = tmp_path / "still.png"
    left = _killed_writer(target)
    assert not target.exists()
    save_image(np.zeros((4, 5, 3), dtype=np.uint8), target)  # a minute has not passed: it may be a live writer
    assert left.exists()
    _age(left, STALE_S + 1)
    save_image(np.zeros((4, 5, 3), dtype=np.uint8), target)
    assert not left.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["still.png"]


def test_leftovers_of_a_running_process_or_of_another_target_stay(tmp_path: Path) -> None:
    from servoface.sim.render.atomic import STALE_S, remove_leftovers

    target = tmp_path / "clip.mp4"
    running = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        mine = tmp_path / f".clip.mp4{PARTIAL}{running.pid}-0123abcd.mp4"  # a writer still at work
        other = tmp_path / f".clip.gif{PARTIAL}999999999-0123abcd.gif"  # another target's
        odd = tmp_path / f".clip.mp4{PARTIAL}notes.txt"  # not a name atomic_output makes
        huge = tmp_path / f".clip.mp4{PARTIAL}{10**20}-0123abcd.mp4"  # no process has that id (os.kill overflows)
        wide = tmp_path / f".clip.mp4{PARTIAL}{2**31}-0123abcd.mp4"
        for p in (mine, other, odd, huge, wide):
            p.write_bytes(b"x")
            _age(p, STALE_S + 1)
        dead = _killed_writer(target)
        _age(dead, STALE_S + 1)
        assert remove_leftovers(target) == [dead]
        assert mine.exists() and other.exists() and odd.exists() and huge.exists() and wide.exists()
    finally:
        running.kill()
        running.wait()
