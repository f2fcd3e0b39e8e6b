// Image files written in the browser: OpenEXR (half floats, uncompressed
// scanlines) and PNG (8-bit RGBA), and handing a file to the user.

// Appends bytes little-endian; grows as needed.
class Bytes {
	constructor(size = 1024) {
		this.buf = new Uint8Array(size);
		this.view = new DataView(this.buf.buffer);
		this.n = 0;
	}

	room(k) {
		if (this.n + k <= this.buf.length)
			return;
		let size = this.buf.length * 2;
		while (size < this.n + k)
			size *= 2;
		const b = new Uint8Array(size);
		b.set(this.buf.subarray(0, this.n));
		this.buf = b;
		this.view = new DataView(b.buffer);
	}

	u8(v) { this.room(1); this.buf[this.n++] = v; }
	i32(v) { this.room(4); this.view.setInt32(this.n, v, true); this.n += 4; }
	u32(v) { this.room(4); this.view.setUint32(this.n, v, true); this.n += 4; }
	u64(v) { this.room(8); this.view.setBigUint64(this.n, BigInt(v), true); this.n += 8; }
	f32(v) { this.room(4); this.view.setFloat32(this.n, v, true); this.n += 4; }
	u16(v) { this.room(2); this.view.setUint16(this.n, v, true); this.n += 2; }
	bytes(a) { this.room(a.length); this.buf.set(a, this.n); this.n += a.length; }
	str(s) { for (let i = 0; i < s.length; i++) this.u8(s.charCodeAt(i) & 0x7f); this.u8(0); }
	result() { return this.buf.slice(0, this.n); }
}

// One header attribute: name, type, size, value (written by fill).
function attribute(out, name, type, size, fill) {
	out.str(name);
	out.str(type);
	out.i32(size);
	const start = out.n;
	fill(out);
	if (out.n - start !== size)
		throw new Error(`EXR attribute ${name}: wrote ${out.n - start} bytes, declared ${size}`);
}

// An OpenEXR file (single part, scanline, no compression) of width x
// height pixels. `half` holds 4 half floats a pixel as 16-bit integers, in
// the order R, G, B, A, rows top first: the rgba16f tiles' pixels, linear
// and premultiplied, which is what OpenEXR's RGBA means. The file stores
// the channels sorted by name, as OpenEXR requires: A, B, G, R; each
// scanline block is one row: y, the byte count, then the row of each
// channel in turn.
export function encodeExr(width, height, half) {
	if (!(width > 0 && height > 0) || half.length !== width * height * 4)
		throw new Error(`EXR: ${half.length} values for ${width}x${height} RGBA pixels`);
	const channels = [['A', 3], ['B', 2], ['G', 1], ['R', 0]];
	const out = new Bytes(1024 + height * (16 + width * 8));
	out.u32(20000630);            // magic 0x762f3101
	out.u32(2);                   // version 2, single-part scanline, short names
	attribute(out, 'channels', 'chlist', channels.length * 18 + 1, (o) => {
		for (const [name] of channels) {
			o.str(name);
			o.i32(1);             // HALF
			o.u8(0);              // pLinear
			o.u8(0); o.u8(0); o.u8(0);
			o.i32(1);             // x sampling
			o.i32(1);             // y sampling
		}
		o.u8(0);
	});
	attribute(out, 'compression', 'compression', 1, (o) => o.u8(0));   // NO_COMPRESSION
	const box = (o) => { o.i32(0); o.i32(0); o.i32(width - 1); o.i32(height - 1); };
	attribute(out, 'dataWindow', 'box2i', 16, box);
	attribute(out, 'displayWindow', 'box2i', 16, box);
	attribute(out, 'lineOrder', 'lineOrder', 1, (o) => o.u8(0));       // INCREASING_Y
	attribute(out, 'pixelAspectRatio', 'float', 4, (o) => o.f32(1));
	attribute(out, 'screenWindowCenter', 'v2f', 8, (o) => { o.f32(0); o.f32(0); });
	attribute(out, 'screenWindowWidth', 'float', 4, (o) => o.f32(1));
	out.u8(0);                    // end of the header

	const rowBytes = width * 2 * channels.length;
	const first = out.n + height * 8;
	for (let y = 0; y < height; y++)
		out.u64(first + y * (8 + rowBytes));
	for (let y = 0; y < height; y++) {
		out.i32(y);
		out.i32(rowBytes);
		const row = y * width * 4;
		for (const [, c] of channels)
			for (let x = 0; x < width; x++)
				out.u16(half[row + x * 4 + c]);
	}
	return out.result();
}

let crcTable = null;

function crc32(bytes, crc = 0xffffffff) {
	if (!crcTable) {
		crcTable = new Uint32Array(256);
		for (let n = 0; n < 256; n++) {
			let c = n;
			for (let k = 0; k < 8; k++)
				c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
			crcTable[n] = c >>> 0;
		}
	}
	for (let i = 0; i < bytes.length; i++)
		crc = crcTable[(crc ^ bytes[i]) & 0xff] ^ (crc >>> 8);
	return crc;
}

function pngChunk(out, type, data) {
	const head = new Uint8Array(8);
	const v = new DataView(head.buffer);
	v.setUint32(0, data.length);
	for (let i = 0; i < 4; i++)
		head[4 + i] = type.charCodeAt(i);
	out.push(head, data);
	const crc = new Uint8Array(4);
	new DataView(crc.buffer).setUint32(0, (crc32(data, crc32(head.subarray(4))) ^ 0xffffffff) >>> 0);
	out.push(crc);
}

// A PNG (8-bit RGBA, every row with the Up filter) of the pixels exactly
// as given, alpha included. A canvas's own toBlob() would go through its
// premultiplied store and change the colour of pixels with partial alpha,
// so the PNG is written here, with the browser's zlib (CompressionStream).
export async function encodePng(width, height, rgba) {
	const stride = width * 4;
	const filtered = new Uint8Array(height * (stride + 1));
	for (let y = 0; y < height; y++) {
		const o = y * (stride + 1);
		filtered[o] = 2;                      // Up: each byte less the one above
		for (let i = 0; i < stride; i++) {
			const above = y ? rgba[(y - 1) * stride + i] : 0;
			filtered[o + 1 + i] = (rgba[y * stride + i] - above) & 0xff;
		}
	}
	const stream = new Blob([filtered]).stream().pipeThrough(new CompressionStream('deflate'));
	const idat = new Uint8Array(await new Response(stream).arrayBuffer());
	const ihdr = new Uint8Array(13);
	const v = new DataView(ihdr.buffer);
	v.setUint32(0, width);
	v.setUint32(4, height);
	ihdr.set([8, 6, 0, 0, 0], 8);             // 8 bits, RGBA, deflate, filters, not interlaced
	const parts = [new Uint8Array([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a])];
	pngChunk(parts, 'IHDR', ihdr);
	pngChunk(parts, 'IDAT', idat);
	pngChunk(parts, 'IEND', new Uint8Array(0));
	return new Blob(parts, {type: 'image/png'});
}

export function canEncodePng() {
	return typeof CompressionStream === 'function';
}

// Offers a Blob to the user as a download named `name`.
export function download(blob, name) {
	const a = document.createElement('a');
	a.href = URL.createObjectURL(blob);
	a.download = name;
	a.hidden = true;
	document.body.append(a);
	a.click();
	a.remove();
	setTimeout(() => URL.revokeObjectURL(a.href), 30000);
}
