"""Key files (formats, permissions, generation) and persisted signing timestamps."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from companion.contracts.errors import UserError
from companion.contracts.signing import Signing
from companion.group.codec import Decoder, Dropped, encode
from companion.group.keys import (
    TimestampFile,
    generate_key_file,
    load_key,
    signing_from_key_file,
    timestamp_path,
)
from companion.group.messages import MemberState

KEY = bytes(range(100, 132))


def write(path: Path, data: bytes, mode: int = 0o600) -> Path:
    path.write_bytes(data)
    os.chmod(path, mode)
    return path


@pytest.mark.parametrize(
    "data",
    [KEY, KEY.hex().encode(), KEY.hex().upper().encode() + b"\n", b"  " + KEY.hex().encode()],
)
def test_key_file_raw_or_hex(tmp_path: Path, data: bytes) -> None:
    assert load_key(write(tmp_path / "k", data)) == KEY


@pytest.mark.parametrize("data", [b"", KEY[:31], KEY + b"x", b"zz" * 32, KEY.hex()[:-1].encode()])
def test_key_file_with_wrong_content_is_refused(tmp_path: Path, data: bytes) -> None:
    with pytest.raises(UserError, match="32 raw bytes or 64 hex"):
        load_key(write(tmp_path / "k", data))


@pytest.mark.parametrize("mode", [0o644, 0o640, 0o604, 0o620, 0o602, 0o660])
def test_key_file_open_to_group_or_others_is_refused_with_the_fix(
    tmp_path: Path, mode: int
) -> None:
    path = write(tmp_path / "fleet.key", KEY, mode)
    with pytest.raises(UserError) as exc:
        load_key(path)
    assert str(path) in str(exc.value) and f"chmod 600 {path}" in str(exc.value)


@pytest.mark.parametrize("mode", [0o600, 0o400])
def test_owner_only_key_file_is_accepted(tmp_path: Path, mode: int) -> None:
    assert load_key(write(tmp_path / "k", KEY, mode)) == KEY


def test_missing_key_file_and_directory_are_user_errors(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="cannot read key file"):
        load_key(tmp_path / "absent")
    with pytest.raises(UserError, match="not a regular file"):
        load_key(tmp_path)


def test_generated_key_file_is_0600_loadable_random_and_never_overwritten(tmp_path: Path) -> None:
    old = os.umask(0o000)  # even with a permissive umask
    try:
        a = generate_key_file(tmp_path / "a.key")
    finally:
        os.umask(old)
    b = generate_key_file(tmp_path / "b.key")
    assert stat.S_IMODE((tmp_path / "a.key").stat().st_mode) == 0o600
    assert load_key(tmp_path / "a.key") == a and load_key(tmp_path / "b.key") == b
    assert a != b and len(a) == 32
    with pytest.raises(UserError, match="refusing to overwrite"):
        generate_key_file(tmp_path / "a.key")
    assert load_key(tmp_path / "a.key") == a


def test_timestamp_file_round_trip_and_corruption(tmp_path: Path) -> None:
    store = TimestampFile(tmp_path / "ts")
    assert store.load() == 0
    store.save(123_456_789_012)
    assert store.load() == 123_456_789_012
    assert stat.S_IMODE((tmp_path / "ts").stat().st_mode) == 0o600
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ts"]  # no temporary left
    (tmp_path / "ts").write_text("garbage\n")
    with pytest.raises(UserError, match="corrupt"):
        store.load()


def test_timestamp_path_per_key_and_sysid(tmp_path: Path) -> None:
    k = tmp_path / "fleet.key"
    p1 = timestamp_path(k, KEY, 3)
    assert p1.parent == tmp_path and p1.name.startswith("fleet.key.")
    assert timestamp_path(k, KEY, 4) != p1
    assert timestamp_path(k, bytes(32), 3) != p1  # a new key starts afresh
    assert timestamp_path(k, KEY, 3, tmp_path / "state").parent == tmp_path / "state"


class Clock:
    def __init__(self, t: float) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t


def test_restart_through_the_state_file_keeps_replays_out(tmp_path: Path) -> None:
    key_file = write(tmp_path / "fleet.key", KEY.hex().encode())
    clock = Clock(1_700_000_000.0)
    receiver = Decoder(1, Signing(KEY, Clock(1_700_000_000.0)))
    first = signing_from_key_file(key_file, 3, clock=clock)
    old = encode(MemberState(3, 1.0, 0j, 0.0), 3, first)
    assert isinstance(receiver.feed(old), MemberState)
    assert list(tmp_path.glob("*.sysid3.signing-ts"))
    clock.t -= 3600.0  # new process, wall clock an hour behind
    second = signing_from_key_file(key_file, 3, clock=clock)
    assert isinstance(receiver.feed(encode(MemberState(3, 2.0, 0j, 0.0), 3, second)), MemberState)
    got = receiver.feed(old)
    assert isinstance(got, Dropped) and got.reason == "replayed"


def test_keygen_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from companion.commands.main import main

    assert main(["keygen", str(tmp_path / "k")]) == 0
    key = load_key(tmp_path / "k")
    assert key.hex() not in capsys.readouterr().out  # the key is never printed
    assert main(["keygen", str(tmp_path / "k")]) == 2
    assert "refusing to overwrite" in capsys.readouterr().err
