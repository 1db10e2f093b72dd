"""Repairing the file of a killed run: HDF5's "open for writing" flag cleared in the
superblock, with the superblock's checksum recomputed."""

from __future__ import annotations

from pathlib import Path

from labrig.errors import InputError


def clear_write_flag(path: str | Path) -> bool:
    """Clear the "open for writing" flag a killed writer leaves (what h5clear -s does).

    Superblock versions 2 and 3 keep the file-consistency flags in byte 11 and end with
    a Jenkins lookup3 checksum of the superblock, which is recomputed. Returns True if
    the flag was set and is now cleared.
    """
    path = Path(path)
    with open(path, "r+b") as handle:
        header = handle.read(8)
        if header != b"\x89HDF\r\n\x1a\n":
            raise InputError(f"{path}: not an HDF5 file (no superblock signature at offset 0)")
        version = handle.read(1)[0]
        if version < 2:
            return False
        offsets, _lengths, flags = handle.read(3)
        size = 12 + 4 * offsets  # base, extension, EOF, root object header addresses
        handle.seek(0)
        superblock = bytearray(handle.read(size))
        if flags == 0:
            return False
        superblock[11] = 0
        handle.seek(0)
        handle.write(bytes(superblock))
        handle.write(lookup3(bytes(superblock)).to_bytes(4, "little"))
    return True


def lookup3(data: bytes, initval: int = 0) -> int:
    """Bob Jenkins' lookup3 ``hashlittle``, the checksum HDF5 uses for metadata."""
    mask = 0xFFFFFFFF

    def rot(x: int, k: int) -> int:
        return ((x << k) | (x >> (32 - k))) & mask

    length = len(data)
    a = b = c = (0xDEADBEEF + length + initval) & mask
    offset = 0
    while length > 12:
        a = (a + int.from_bytes(data[offset : offset + 4], "little")) & mask
        b = (b + int.from_bytes(data[offset + 4 : offset + 8], "little")) & mask
        c = (c + int.from_bytes(data[offset + 8 : offset + 12], "little")) & mask
        a, b, c = _mix(a, b, c, rot)
        offset += 12
        length -= 12
    if length == 0:
        return c
    tail = data[offset:] + b"\x00" * (12 - length)
    a = (a + int.from_bytes(tail[0:4], "little")) & mask
    b = (b + int.from_bytes(tail[4:8], "little")) & mask
    c = (c + int.from_bytes(tail[8:12], "little")) & mask
    return _final(a, b, c, rot)


def _mix(a: int, b: int, c: int, rot) -> tuple[int, int, int]:
    mask = 0xFFFFFFFF
    a = (a - c) & mask
    a ^= rot(c, 4)
    c = (c + b) & mask
    b = (b - a) & mask
    b ^= rot(a, 6)
    a = (a + c) & mask
    c = (c - b) & mask
    c ^= rot(b, 8)
    b = (b + a) & mask
    a = (a - c) & mask
    a ^= rot(c, 16)
    c = (c + b) & mask
    b = (b - a) & mask
    b ^= rot(a, 19)
    a = (a + c) & mask
    c = (c - b) & mask
    c ^= rot(b, 4)
    b = (b + a) & mask
    return a, b, c


def _final(a: int, b: int, c: int, rot) -> int:
    mask = 0xFFFFFFFF
    c ^= b
    c = (c - rot(b, 14)) & mask
    a ^= c
    a = (a - rot(c, 11)) & mask
    b ^= a
    b = (b - rot(a, 25)) & mask
    c ^= b
    c = (c - rot(b, 16)) & mask
    a ^= c
    a = (a - rot(c, 4)) & mask
    b ^= a
    b = (b - rot(a, 14)) & mask
    c ^= b
    c = (c - rot(b, 24)) & mask
    return c
