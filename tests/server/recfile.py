# SPDX-License-Identifier: GPL-3.0-or-later
"""Reading and writing session recordings (docs/server.md, "Session
recording"; format 2: chunks of entries, each with its CRC-32C) in the tests
that alter a recording on purpose (server_session.sh, record mode): just the
wire format, no generated code. An altered recording is resealed (its
checksums made right again), so that what the test changed reaches the
replay rather than being refused as damage."""

import struct

MAGIC = b"FTMREC2\n"
HEAD = 36  # "FTMC", body length, entries, body CRC, first and last tick, head CRC


def _table():
    t = []
    for i in range(256):
        c = i
        for _ in range(8):
            c = (c >> 1) ^ (0x82f63b78 if c & 1 else 0)
        t.append(c)
    return t


_T = _table()


def crc32c(b):
    """CRC-32C (Castagnoli) of b, as server/crc32c.c."""
    c = 0xffffffff
    for x in b:
        c = (c >> 8) ^ _T[(c ^ x) & 0xff]
    return c ^ 0xffffffff

def varint(b, i):
    """The base-128 varint at b[i]: (value, index after it)."""
    v = s = 0
    while True:
        c = b[i]
        i += 1
        v |= (c & 0x7f) << s
        s += 7
        if not c & 0x80:
            return v, i


def put(v):
    """v as a base-128 varint."""
    out = bytearray()
    while True:
        c = v & 0x7f
        v >>= 7
        out.append(c | (0x80 if v else 0))
        if not v:
            return bytes(out)


def fields(b, i=0, end=None):
    """The fields of the message in b[i:end]: (field, wire type, value, at),
    value an int (varint) or the bytes, at the offset in b where the value's
    bytes start (for a nested message: where to read its fields)."""
    end = len(b) if end is None else end
    while i < end:
        key, i = varint(b, i)
        f, t = key >> 3, key & 7
        if t == 0:
            v, j = varint(b, i)
        elif t == 1:
            v, j = bytes(b[i:i + 8]), i + 8
        elif t == 2:
            n, i = varint(b, i)
            v, j = bytes(b[i:i + n]), i + n
        elif t == 5:
            v, j = bytes(b[i:i + 4]), i + 4
        else:
            raise SystemExit("bad wire type %d at byte %d" % (t, i))
        yield f, t, v, i
        i = j


def encode(fs):
    """A message from (field, wire type, value) triples (or fields' 4-tuples)."""
    out = bytearray()
    for f, t, v, *_ in fs:
        out += put(f << 3 | t)
        out += put(v) if t == 0 else (put(len(v)) + v if t == 2 else v)
    return bytes(out)


def chunks(data):
    """The chunks after the magic: (offset of the head, of the body, body
    length, entry count)."""
    i = 8
    while i < len(data):
        n, count = struct.unpack_from("<II", data, i + 4)
        yield i, i + HEAD, n, count
        i += HEAD + n


def _spans(data):
    """Each entry: (offset of its bytes, their length)."""
    for _, body, n, count in chunks(data):
        i = body
        for _ in range(count):
            m, j = varint(data, i)
            yield j, m
            i = j + m + 4


def entries(data):
    """The entries: (offset of the entry's bytes, its fields as a list)."""
    for at, n in _spans(data):
        yield at, list(fields(data, at, at + n))


def bodies(data):
    """The entries' bytes, header first."""
    return [bytes(data[at:at + n]) for at, n in _spans(data)]


def entry(fs):
    """An entry's bytes from its fields (for chunk(), append(), build())."""
    return encode(fs)


def _tick(body):
    return next((v for f, t, v, a in fields(body) if f == 2 and t == 0), 0)


def chunk(bs):
    """A chunk of the entries' bytes bs, checksums included."""
    body = b"".join(put(len(b)) + b + struct.pack("<I", crc32c(b)) for b in bs)
    head = b"FTMC" + struct.pack("<IIIQQ", len(body), len(bs), crc32c(body), _tick(bs[0]),
                                 _tick(bs[-1]))
    return head + struct.pack("<I", crc32c(head)) + body


def append(data, bs):
    """data with a chunk of the entries bs after its last."""
    return bytes(data) + chunk(bs)


def build(bs):
    """A recording of the entries bs (the header first, in a chunk of its
    own, as the server writes it)."""
    return MAGIC + chunk(bs[:1]) + (chunk(bs[1:]) if len(bs) > 1 else b"")


def reseal(data):
    """data, altered in place without changing any length, with its
    checksums made right again."""
    data = bytearray(data)
    for head, body, n, count in chunks(data):
        i = body
        for _ in range(count):
            m, j = varint(data, i)
            struct.pack_into("<I", data, j + m, crc32c(data[j:j + m]))
            i = j + m + 4
        struct.pack_into("<I", data, head + 12, crc32c(data[body:body + n]))
        struct.pack_into("<I", data, head + 32, crc32c(data[head:head + 32]))
    return bytes(data)


# RecordEntry fields (proto/ftm.proto) and the kinds of ftm.v1.Kind used here
TICK, KIND, PAYLOAD, INCOMING = 2, 3, 4, 6
KIND_PROBE_INPUT, KIND_TICK_FRAME, KIND_STATUS = 2, 3, 5
