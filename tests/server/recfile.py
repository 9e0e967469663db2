# SPDX-License-Identifier: GPL-3.0-or-later
"""Reading and writing the protobuf of session recordings (docs/server.md,
"Session recording") in the tests that alter a recording on purpose
(server_session.sh, record mode): just the wire format, no generated code."""


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


def entries(data):
    """The entries after the 8-byte magic: (offset of the entry's bytes, its
    fields as a list)."""
    i = 8
    while i < len(data):
        n, i = varint(data, i)
        yield i, list(fields(data, i, i + n))
        i += n


def entry(fs):
    """An entry, length prefix included, ready to append to a recording."""
    body = encode(fs)
    return put(len(body)) + body


# RecordEntry fields (proto/ftm.proto) and the kinds of ftm.v1.Kind used here
TICK, KIND, PAYLOAD, INCOMING = 2, 3, 4, 6
KIND_PROBE_INPUT, KIND_TICK_FRAME, KIND_STATUS = 2, 3, 5
