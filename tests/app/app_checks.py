"""What the app tests share: failures collected and reported, a command run with its exit code
checked, and a PNG's pixels read without PIL (Python's zlib and struct only)."""
import struct
import subprocess
import zlib

failures = []


def fail(what):
    failures.append(what)
    print("FAIL " + what, flush=True)


def run(args, expect=None, env=None, timeout=600):
    p = subprocess.run(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                       timeout=timeout, env=env)
    if expect is not None and p.returncode not in expect:
        fail("%s: exit %d, expected %s\n  %s" % (" ".join(args[:4]), p.returncode, expect,
                                                 p.stderr.strip()[:600]))
    return p


def png_header_and_data(path):
    """(width, height, bit depth, colour type, interlace, decompressed scanlines) of a PNG."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(path + ": not a PNG")
    at, idat, header = 8, b"", None
    while at < len(data):
        size, kind = struct.unpack(">I4s", data[at:at + 8])
        body = data[at + 8:at + 8 + size]
        at += 12 + size
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
    if header is None:
        raise ValueError(path + ": no IHDR")
    width, height, depth, colour, _, _, interlace = header
    return width, height, depth, colour, interlace, zlib.decompress(idat)


def read_png(path):
    """(width, height, rows of RGB tuples) of an 8-bit RGB or RGBA PNG, without PIL."""
    width, height, depth, colour, interlace, raw = png_header_and_data(path)
    if depth != 8 or colour not in (2, 6) or interlace:
        raise ValueError("%s: PNG type %d/%d not read here" % (path, depth, colour))
    bpp = 3 if colour == 2 else 4
    stride = width * bpp
    rows, prev, pos = [], bytearray(stride), 0
    for _ in range(height):
        kind, line = raw[pos], bytearray(raw[pos + 1:pos + 1 + stride])
        pos += 1 + stride
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if kind == 1:
                line[i] = (line[i] + a) & 255
            elif kind == 2:
                line[i] = (line[i] + b) & 255
            elif kind == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append([tuple(line[i:i + 3]) for i in range(0, stride, bpp)])
        prev = line
    return width, height, rows
