"""Catalogue back-ends for the tests: a SQLite file, and a real PostgreSQL server.

The PostgreSQL server is the Debian package's (``/usr/lib/postgresql/*/bin``), started once
per session by ``initdb`` + ``pg_ctl`` in a throw-away data directory, listening only on a
Unix socket in that directory (no TCP port). PostgreSQL refuses to run as root, so under
root the directory is given to the ``postgres`` user and the server runs as that user
(``runuser``). Every test gets its own fresh database. The tests skip, saying why, only when
the server binaries are not installed (CI installs them: ``.ci/system-packages``).
"""

from __future__ import annotations

import glob
import os
import pwd
import shutil
import subprocess
import tempfile
import uuid
from pathlib import Path

import pytest
import sqlalchemy as sa


def _postgres_bin() -> Path | None:
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"))
    return Path(found[-1]).parent if found else None


def _as_server_user(args: list[str]) -> list[str]:
    if os.geteuid() != 0:
        return args
    return ["runuser", "-u", "postgres", "--", *args]


@pytest.fixture(scope="session")
def postgres_server():
    """Start a throw-away PostgreSQL server; yield its socket directory; stop it."""
    bindir = _postgres_bin()
    if bindir is None:
        pytest.skip("PostgreSQL server binaries (/usr/lib/postgresql/*/bin/initdb) are not "
                    "installed; install the Debian package 'postgresql' to run these tests")
    if os.geteuid() == 0:
        try:
            server_user = pwd.getpwnam("postgres")
        except KeyError:
            pytest.skip("running as root and there is no 'postgres' user to run the server")
    root = Path(tempfile.mkdtemp(prefix="driveid-pg-"))
    data = root / "data"
    if os.geteuid() == 0:
        os.chown(root, server_user.pw_uid, server_user.pw_gid)
    log = root / "server.log"
    subprocess.run(_as_server_user([str(bindir / "initdb"), "-D", str(data), "-A", "trust",
                                    "-U", "postgres", "--no-sync"]),
                   check=True, capture_output=True)
    subprocess.run(_as_server_user([
        str(bindir / "pg_ctl"), "-D", str(data), "-l", str(log), "-w", "-t", "60", "-o",
        f"-k {root} -c listen_addresses='' -c fsync=off", "start"]),
        check=True, capture_output=True)
    try:
        yield root
    finally:
        subprocess.run(_as_server_user([str(bindir / "pg_ctl"), "-D", str(data), "-m", "fast",
                                        "-w", "stop"]), capture_output=True)
        shutil.rmtree(root, ignore_errors=True)


@pytest.fixture(params=["sqlite", "postgresql"])
def catalog_url(request, tmp_path):
    """A URL of an empty catalogue: a SQLite file, or a fresh database on the server."""
    if request.param == "sqlite":
        yield str(tmp_path / "catalog.sqlite")
        return
    socket_dir = request.getfixturevalue("postgres_server")
    name = "t_" + uuid.uuid4().hex[:12]
    admin = sa.create_engine(f"postgresql+psycopg://postgres@/postgres?host={socket_dir}",
                             isolation_level="AUTOCOMMIT")
    with admin.connect() as conn:
        conn.execute(sa.text(f"CREATE DATABASE {name}"))
    yield f"postgresql://postgres@/{name}?host={socket_dir}"
    with admin.connect() as conn:
        conn.execute(sa.text(f"DROP DATABASE IF EXISTS {name} WITH (FORCE)"))
    admin.dispose()
