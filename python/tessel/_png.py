"""A minimal PNG writer (RGB8, zlib from the standard library).

The library renders into memory (tessel_render); PNG encoding lives in the
command-line tool (libpng), which the package does not load. The file is
written next to the destination and renamed over it, as the library's own
writers do: a failed write leaves no partial file.
"""
import os
import struct
import secrets
import zlib

import numpy as np


def _chunk(kind, data):
    body = kind + data
    return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)


def encode(rgb, level=6):
    """PNG bytes of an (H, W, 3) uint8 image."""
    img = np.ascontiguousarray(rgb, dtype=np.uint8)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError("an image must have shape (H, W, 3), got %s" % (img.shape,))
    h, w, _ = img.shape
    rows = np.zeros((h, 1 + 3 * w), dtype=np.uint8)  # filter byte 0 (none) per row
    rows[:, 1:] = img.reshape(h, 3 * w)
    header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)  # 8-bit RGB
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", header) +
            _chunk(b"IDAT", zlib.compress(rows.tobytes(), level)) + _chunk(b"IEND", b""))


def write(path, rgb):
    """Writes an (H, W, 3) uint8 image as PNG, whole or not at all."""
    data = encode(rgb)
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    # O_EXCL with mode 0666: the umask applies, as for any new file.
    tmp = os.path.join(folder, ".%s.%s.tmp" % (os.path.basename(path), secrets.token_hex(6)))
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
