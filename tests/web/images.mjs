// Image readers for the browser tests, written here so that the checks do
// not share code with what they check: PNG (8-bit, every filter type),
// uncompressed scanline OpenEXR with HALF channels (every header field
// checked), half floats, the 8-bit sRGB encoding and the viewer's display
// transform.

import zlib from 'node:zlib';

const CRC_TABLE = (() => {
	const t = new Int32Array(256);
	for (let n = 0; n < 256; n++) {
		let c = n;
		for (let k = 0; k < 8; k++)
			c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
		t[n] = c;
	}
	return t;
})();

// The CRC-32 of PNG chunks (ISO 3309), as an unsigned number.
export function crc32(bytes) {
	let c = -1;
	for (let i = 0; i < bytes.length; i++)
		c = CRC_TABLE[(c ^ bytes[i]) & 0xff] ^ (c >>> 8);
	return (c ^ -1) >>> 0;
}

// {width, height, channels, pixels} of an 8-bit non-interlaced PNG, every
// chunk's CRC checked.
export function decodePng(buf) {
	const sig = [0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a];
	if (buf.length < 8 || sig.some((b, i) => buf[i] !== b))
		throw new Error('not a PNG');
	let pos = 8;
	let ihdr = null;
	const idat = [];
	while (pos + 8 <= buf.length) {
		const n = buf.readUInt32BE(pos);
		const type = buf.toString('latin1', pos + 4, pos + 8);
		const body = buf.subarray(pos + 8, pos + 8 + n);
		if (pos + 12 + n > buf.length)
			throw new Error(`PNG chunk ${type} runs past the end`);
		if (crc32(buf.subarray(pos + 4, pos + 8 + n)) !== buf.readUInt32BE(pos + 8 + n))
			throw new Error(`PNG chunk ${type}: bad CRC`);
		if (type === 'IHDR')
			ihdr = body;
		else if (type === 'IDAT')
			idat.push(body);
		else if (type === 'IEND')
			break;
		pos += 12 + n;
	}
	if (!ihdr)
		throw new Error('PNG without IHDR');
	const width = ihdr.readUInt32BE(0);
	const height = ihdr.readUInt32BE(4);
	const depth = ihdr[8];
	const channels = {0: 1, 2: 3, 4: 2, 6: 4}[ihdr[9]];
	if (depth !== 8 || !channels || ihdr[12] !== 0)
		throw new Error(`PNG of depth ${depth}, colour type ${ihdr[9]}, interlace ${ihdr[12]}`);
	const raw = zlib.inflateSync(Buffer.concat(idat));
	const stride = width * channels;
	const out = Buffer.alloc(stride * height);
	for (let y = 0; y < height; y++) {
		const f = raw[y * (stride + 1)];
		const line = raw.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1));
		for (let i = 0; i < stride; i++) {
			const a = i >= channels ? out[y * stride + i - channels] : 0;
			const b = y ? out[(y - 1) * stride + i] : 0;
			const c = y && i >= channels ? out[(y - 1) * stride + i - channels] : 0;
			let pred = 0;
			if (f === 1) {
				pred = a;
			} else if (f === 2) {
				pred = b;
			} else if (f === 3) {
				pred = (a + b) >> 1;
			} else if (f === 4) {
				const p = a + b - c;
				const pa = Math.abs(p - a);
				const pb = Math.abs(p - b);
				const pc = Math.abs(p - c);
				pred = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
			} else if (f !== 0) {
				throw new Error(`PNG filter type ${f}`);
			}
			out[y * stride + i] = (line[i] + pred) & 255;
		}
	}
	return {width, height, channels, pixels: out};
}

export function halfToFloat(h) {
	const s = h & 0x8000 ? -1 : 1;
	const e = (h >> 10) & 0x1f;
	const m = h & 0x3ff;
	if (e === 0)
		return s * m * 2 ** -24;
	if (e === 31)
		return m ? NaN : s * Infinity;
	return s * (1 + m / 1024) * 2 ** (e - 15);
}

export function srgb8(l) {
	if (!(l > 0))
		return 0;
	if (l >= 1)
		return 255;
	const e = l <= 0.0031308 ? 12.92 * l : 1.055 * l ** (1 / 2.4) - 0.055;
	return Math.floor(255 * e + 0.5);
}

// Every check an uncompressed scanline OpenEXR with HALF channels allows;
// returns {attrs, channels, width, height, planes: {name: Uint16Array}} or
// throws naming the first problem.
export function parseExr(buf) {
	const fail = (why) => {
		throw new Error(`EXR: ${why}`);
	};
	if (buf.length < 8 || buf.readUInt32LE(0) !== 20000630)
		fail('no OpenEXR magic 76 2f 31 01');
	const version = buf.readUInt32LE(4);
	if ((version & 0xff) !== 2)
		fail(`version ${version & 0xff}, expected 2`);
	if (version & ~0xff)
		fail(`flags 0x${(version & ~0xff).toString(16)}: not a plain single-part scanline file`);
	let pos = 8;
	const cstr = () => {
		const end = buf.indexOf(0, pos);
		if (end < 0 || end - pos > 255)
			fail(`unterminated name at byte ${pos}`);
		const s = buf.toString('latin1', pos, end);
		pos = end + 1;
		return s;
	};
	const attrs = {};
	for (;;) {
		if (pos >= buf.length)
			fail('header without its end');
		if (buf[pos] === 0) {
			pos++;
			break;
		}
		const name = cstr();
		const type = cstr();
		const size = buf.readInt32LE(pos);
		pos += 4;
		if (size < 0 || pos + size > buf.length)
			fail(`attribute ${name} of size ${size}`);
		attrs[name] = {type, size, data: buf.subarray(pos, pos + size)};
		pos += size;
	}
	const want = {channels: 'chlist', compression: 'compression', dataWindow: 'box2i',
		      displayWindow: 'box2i', lineOrder: 'lineOrder', pixelAspectRatio: 'float',
		      screenWindowCenter: 'v2f', screenWindowWidth: 'float'};
	for (const [name, type] of Object.entries(want)) {
		if (!attrs[name])
			fail(`no ${name} attribute`);
		if (attrs[name].type !== type)
			fail(`${name} is of type ${attrs[name].type}, not ${type}`);
	}
	const ch = attrs.channels.data;
	const channels = [];
	for (let p = 0; ch[p] !== 0;) {
		const end = ch.indexOf(0, p);
		if (end < 0)
			fail('channel list without its end');
		const name = ch.toString('latin1', p, end);
		p = end + 1;
		channels.push({name, type: ch.readInt32LE(p), pLinear: ch[p + 4],
			       xs: ch.readInt32LE(p + 8), ys: ch.readInt32LE(p + 12)});
		p += 16;
		if (p >= ch.length)
			fail('channel list without its end');
	}
	if (attrs.compression.data[0] !== 0)
		fail(`compression ${attrs.compression.data[0]}, expected 0 (none)`);
	if (attrs.lineOrder.data[0] !== 0)
		fail(`line order ${attrs.lineOrder.data[0]}, expected 0 (increasing y)`);
	const box = (d) => [d.readInt32LE(0), d.readInt32LE(4), d.readInt32LE(8), d.readInt32LE(12)];
	const dw = box(attrs.dataWindow.data);
	const width = dw[2] - dw[0] + 1;
	const height = dw[3] - dw[1] + 1;
	if (width <= 0 || height <= 0)
		fail(`data window ${dw}`);
	const bytesPerPixel = channels.reduce((s, c) => s + (c.type === 1 ? 2 : 4), 0);
	const rowBytes = width * bytesPerPixel;
	const planes = {};
	for (const c of channels)
		planes[c.name] = new Uint16Array(width * height);
	let end = pos + height * 8;
	for (let i = 0; i < height; i++) {
		const off = Number(buf.readBigUInt64LE(pos + 8 * i));
		if (off + 8 + rowBytes > buf.length)
			fail(`scanline ${i} at ${off} runs past the end of the file`);
		const y = buf.readInt32LE(off);
		const n = buf.readInt32LE(off + 4);
		if (y !== dw[1] + i || n !== rowBytes)
			fail(`scanline block ${i}: y ${y}, ${n} bytes (expected ${dw[1] + i}, ${rowBytes})`);
		let p = off + 8;
		for (const c of channels) {
			if (c.type !== 1)
				fail(`channel ${c.name} is not HALF`);
			for (let x = 0; x < width; x++, p += 2)
				planes[c.name][i * width + x] = buf.readUInt16LE(p);
		}
		end = Math.max(end, off + 8 + rowBytes);
	}
	if (end !== buf.length)
		fail(`${buf.length - end} bytes after the last scanline`);
	return {attrs, channels, dataWindow: dw, displayWindow: box(attrs.displayWindow.data),
		width, height, planes};
}

// The display transform as documented in clients/web/image.js, computed
// here on its own.
export function displayed(v, stops, gamma) {
	const e = v / 255;
	const lin = e <= 0.04045 ? e / 12.92 : ((e + 0.055) / 1.055) ** 2.4;
	const l = Math.min(1, (lin * 2 ** stops) ** (2.2 / gamma));
	const enc = l <= 0 ? 0 : l <= 0.0031308 ? 12.92 * l : 1.055 * l ** (1 / 2.4) - 0.055;
	return Math.round(255 * enc);
}
