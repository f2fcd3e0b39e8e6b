# Read the pixels of a scanline OpenEXR file (uncompressed or ZIP, as relight
# writes them) without the OpenEXR module, for the tests that look at regions.
import struct, zlib

def read(path):
	"""A scanline OpenEXR of no or ZIP compression: {channel: rows of values, top first}."""
	d = open(path, "rb").read()
	assert d[:4] == b"\x76\x2f\x31\x01", "not OpenEXR"
	pos, attrs = 8, {}
	while d[pos] != 0:
		e = d.index(b"\0", pos)
		name = d[pos:e].decode()
		e2 = d.index(b"\0", e + 1)
		size, = struct.unpack("<i", d[e2 + 1:e2 + 5])
		attrs[name] = d[e2 + 5:e2 + 5 + size]
		pos = e2 + 5 + size
	pos += 1
	chans, p = [], 0
	cl = attrs["channels"]
	while cl[p] != 0:
		e = cl.index(b"\0", p)
		ptype, = struct.unpack("<i", cl[e + 1:e + 5])
		chans.append((cl[p:e].decode(), ptype))
		p = e + 17
	x0, y0, x1, y1 = struct.unpack("<4i", attrs["dataWindow"])
	w, h = x1 - x0 + 1, y1 - y0 + 1
	comp = attrs["compression"][0]
	assert comp in (0, 3), "compression %d" % comp
	lines = 1 if comp == 0 else 16
	nblocks = (h + lines - 1) // lines
	offs = struct.unpack("<%dQ" % nblocks, d[pos:pos + 8 * nblocks])
	out = {c: [] for c, _ in chans}
	for off in offs:
		y, n = struct.unpack("<ii", d[off:off + 8])
		raw = d[off + 8:off + 8 + n]
		rows = min(lines, y1 + 1 - y)
		size = sum(w * (2 if t == 1 else 4) for _, t in chans) * rows
		if n < size:
			t = bytearray(zlib.decompress(raw))
			for i in range(1, len(t)):
				t[i] = (t[i - 1] + t[i] - 128) & 0xff
			half = (len(t) + 1) // 2
			raw = bytearray(len(t))
			raw[0::2] = t[:half]
			raw[1::2] = t[half:]
			raw = bytes(raw)
		p = 0
		for r in range(rows):
			for c, ty in chans:
				fmt, sz = ("<%de" % w, 2) if ty == 1 else ("<%df" % w, 4)
				out[c].append(struct.unpack(fmt, raw[p:p + w * sz]))
				p += w * sz
	return out
