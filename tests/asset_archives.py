"""Archives laid out as the official downloads, made from the assets in use, and a loopback server
for them: how the tests rehearse a machine that has no local copies and must download.

Run as ``python -m tests.asset_archives --ycb DIR --hand DIR`` to serve them until interrupted; it
prints the ``--workflow-config`` line (for pytest or snakemake) that points the downloads at it.

The YCB archives hold each object's ``textured.obj`` at ``<id>/google_16k/textured.obj``, byte for
byte, so the object sets' pinned sha256 verify them. The hand archive holds the upstream layout at
the pinned commit: a local copy's patched MJCF is replaced by its ``*.upstream`` twin (pinned), and
the three upstream meshes a local copy may lack (``ABSENT_LOCALLY_OK``: unpinned, and no hand the
pipeline builds uses them) are stood in for by the palm's core mesh, so that the description's own
scene still loads.
"""

from __future__ import annotations

import argparse
import functools
import http.server
import io
import sys
import tarfile
import threading
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from graspstab.assets.hand import ABSENT_LOCALLY_OK, HAND_COMMIT, RIGHT_MESH_DIR
from graspstab.assets.ycb import MESH_NAME, archive_member
from graspstab.hand.names import PALM_CORE_STL

YCB_ARCHIVE = "{id}_google_16k.tgz"
HAND_ARCHIVE = "{commit}.tar.gz"


def _write_tgz(path: Path, members: Iterable[tuple[str, bytes]]) -> Path:
    """A gzipped tar of ``members`` (name, bytes), written whole before it is renamed into place."""
    part = path.with_name(path.name + ".part")
    with tarfile.open(part, "w:gz", compresslevel=1) as tf:
        for name, data in members:
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tf.addfile(info, io.BytesIO(data))
    part.replace(path)
    return path


def write_ycb_archives(ycb_dir: Path, object_ids: Iterable[str], out: Path) -> list[Path]:
    """One google_16k-style archive per object, from ``<ycb_dir>/<id>/textured.obj``."""
    out.mkdir(parents=True, exist_ok=True)
    return [
        _write_tgz(
            out / YCB_ARCHIVE.format(id=oid),
            [(archive_member(oid), (ycb_dir / oid / MESH_NAME).read_bytes())],
        )
        for oid in object_ids
    ]


def upstream_hand_files(hand_dir: Path) -> dict[str, bytes]:
    """The description's ``v2/`` and ``LICENSE`` in the upstream layout (see the module text)."""
    files: dict[str, bytes] = {"LICENSE": (hand_dir / "LICENSE").read_bytes()}
    for path in sorted((hand_dir / "v2").rglob("*")):
        if path.is_file() and path.suffix != ".upstream":
            files[path.relative_to(hand_dir).as_posix()] = path.read_bytes()
    for path in (hand_dir / "v2").rglob("*.upstream"):  # the twin replaces the patched file
        files[path.relative_to(hand_dir).as_posix().removesuffix(".upstream")] = path.read_bytes()
    core = files[f"{RIGHT_MESH_DIR}/{PALM_CORE_STL}"]
    for rel in sorted(ABSENT_LOCALLY_OK):
        files.setdefault(rel, core)
    return files


def write_hand_archive(hand_dir: Path, out: Path, commit: str = HAND_COMMIT) -> Path:
    """The GitHub-style archive of the description at ``commit`` (top folder repo-commit)."""
    out.mkdir(parents=True, exist_ok=True)
    top = f"orcahand_description-{commit}"
    members = [(f"{top}/{rel}", data) for rel, data in upstream_hand_files(hand_dir).items()]
    return _write_tgz(out / HAND_ARCHIVE.format(commit=commit), members)


def workflow_config_line(base_url: str) -> str:
    """The ``--workflow-config`` / ``--config`` value that downloads from ``base_url``."""
    return f"assets={{ycb_url: '{base_url}/{YCB_ARCHIVE}', hand_url: '{base_url}/{HAND_ARCHIVE}'}}"


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: object) -> None:  # noqa: A002
        pass


@contextmanager
def serve(root: Path, port: int = 0) -> Iterator[str]:
    """Serve ``root`` on 127.0.0.1 (a free port unless given); yield the base URL."""
    handler = functools.partial(_QuietHandler, directory=str(root))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", port), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{httpd.server_address[1]}"
    finally:
        httpd.shutdown()
        httpd.server_close()
        thread.join(timeout=5)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ycb", type=Path, required=True, help="folder of <id>/textured.obj")
    parser.add_argument("--hand", type=Path, required=True, help="orcahand_description copy")
    parser.add_argument("--out", type=Path, required=True, help="folder for the archives")
    parser.add_argument("--port", type=int, default=0)
    args = parser.parse_args(argv)
    ids = sorted(p.name for p in args.ycb.iterdir() if (p / MESH_NAME).is_file())
    write_ycb_archives(args.ycb, ids, args.out)
    write_hand_archive(args.hand, args.out)
    with serve(args.out, args.port) as base:
        print(f"serving {len(ids)} YCB archives and the hand at {base}", flush=True)
        print(f'--workflow-config "{workflow_config_line(base)}"', flush=True)
        try:
            threading.Event().wait()
        except KeyboardInterrupt:
            pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
