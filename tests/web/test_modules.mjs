// The viewer's modules (clients/web) on their own, in node, without a
// browser: tile parsing, the display transform, half floats, the OpenEXR
// and PNG writers, the sliders' ranges. They are read back by the
// independent readers of images.mjs.
//
//   node test_modules.mjs

import path from 'node:path';
import {fileURLToPath, pathToFileURL} from 'node:url';
import {crc32, decodePng, displayed, halfToFloat as refHalf, parseExr} from './images.mjs';

const HERE = path.dirname(fileURLToPath(import.meta.url));
const SOURCE_DIR = process.env.RELIGHT_SOURCE_DIR || path.resolve(HERE, '..', '..');
const NAME = 'web-modules';
const web = (f) => import(pathToFileURL(path.join(SOURCE_DIR, 'clients', 'web', f)).href);

let n = 0;
let failed = 0;

function check(cond, what, detail = '') {
	n++;
	if (!cond) {
		failed++;
		console.error(`${NAME}: FAIL: ${what}${detail ? ` (${detail})` : ''}`);
	}
	return Boolean(cond);
}

function throws(fn, pattern, what) {
	try {
		fn();
	} catch (e) {
		return check(pattern.test(e.message), what, `threw '${e.message}'`);
	}
	return check(false, what, 'no error');
}

// A deterministic pseudo-random sequence (xorshift32).
function random(seed) {
	let x = seed >>> 0 || 1;
	return () => {
		x ^= x << 13;
		x >>>= 0;
		x ^= x >>> 17;
		x ^= x << 5;
		x >>>= 0;
		return x;
	};
}

function tileFrame(fields, pixelBytes, magic = 'RLT1') {
	const b = Buffer.alloc(36 + pixelBytes);
	b.write(magic, 0, 'latin1');
	[fields.header ?? 36, fields.edit, fields.level, fields.format, fields.x, fields.y,
	 fields.width, fields.height].forEach((v, i) => b.writeUInt32LE(v, 4 + 4 * i));
	for (let i = 0; i < pixelBytes; i++)
		b[36 + i] = i & 0xff;
	return b.buffer.slice(b.byteOffset, b.byteOffset + b.length);
}

async function main() {
	const {parseTile} = await web('protocol.js');
	const {displayTable, halfToFloat, linearToSrgb, srgbToLinear} = await web('image.js');
	const {encodeExr, encodePng} = await web('files.js');
	const {sliderRange, formatNumber} = await web('controls.js');

	// Tiles
	const t = parseTile(tileFrame({edit: 7, level: 2, format: 1, x: 128, y: 256, width: 3, height: 2}, 24));
	check(t.edit === 7 && t.level === 2 && t.format === 1 && t.x === 128 && t.y === 256 &&
	      t.width === 3 && t.height === 2, 'an rgba8 tile header', JSON.stringify(t));
	check(t.pixels instanceof Uint8Array && t.pixels.length === 24 && t.pixels[5] === 5,
	      'an rgba8 tile\'s pixels follow the header');
	const h = parseTile(tileFrame({edit: 1, level: 3, format: 2, x: 0, y: 0, width: 2, height: 1}, 16));
	check(h.pixels instanceof Uint16Array && h.pixels.length === 8 && h.pixels[1] === 0x0302,
	      'an rgba16f tile: little-endian half floats', `${h.pixels && h.pixels[1]}`);
	const ok = {edit: 1, level: 0, format: 1, x: 0, y: 0, width: 2, height: 2};
	throws(() => parseTile(new ArrayBuffer(35)), /shorter than/, 'a frame shorter than the header');
	throws(() => parseTile(tileFrame(ok, 16, 'RLT2')), /magic/, 'a bad magic');
	throws(() => parseTile(tileFrame(Object.assign({}, ok, {header: 40}), 16)), /header size/,
	       'a header size other than 36');
	throws(() => parseTile(tileFrame(Object.assign({}, ok, {format: 3}), 16)), /format/,
	       'an unknown format');
	throws(() => parseTile(tileFrame(ok, 15)), /header says/, 'a frame one byte short');
	throws(() => parseTile(tileFrame(ok, 17)), /header says/, 'a frame one byte long');

	// The display transform
	const id = displayTable(0, 2.2);
	check(id.every((v, i) => v === i), 'exposure 0, gamma 2.2: the identity');
	let roundTrip = true;
	for (let v = 0; v < 256; v++)
		roundTrip = roundTrip && Math.round(255 * linearToSrgb(srgbToLinear(v / 255))) === v;
	check(roundTrip, 'every 8-bit sRGB value survives decoding and encoding (the identity is no shortcut)');
	for (const [stops, gamma] of [[1, 2.2], [-2.5, 2.2], [0, 1.8], [3, 2.6], [0.1, 2.2]]) {
		const tab = displayTable(stops, gamma);
		let same = true;
		let monotonic = true;
		for (let v = 0; v < 256; v++) {
			same = same && tab[v] === displayed(v, stops, gamma);
			monotonic = monotonic && (v === 0 || tab[v] >= tab[v - 1]);
		}
		check(same && monotonic, `${stops} stops, gamma ${gamma}: the documented curve, never decreasing`);
	}
	check(displayTable(1, 2.2)[100] > 100 && displayTable(-1, 2.2)[100] < 100 &&
	      displayTable(1, 2.2)[255] === 255 && displayTable(-8, 2.2)[0] === 0,
	      'more stops brighten, fewer darken; white and black stay');

	// Half floats: two implementations agree on all 65536 values.
	let halves = 0;
	for (let v = 0; v < 65536; v++) {
		const a = halfToFloat(v);
		const b = refHalf(v);
		if (a === b || (Number.isNaN(a) && Number.isNaN(b)))
			halves++;
	}
	check(halves === 65536, 'half floats decode like the reference', `${65536 - halves} differ`);
	check(halfToFloat(0x3c00) === 1 && halfToFloat(0xc000) === -2 && halfToFloat(0x7bff) === 65504 &&
	      halfToFloat(0x0001) === 2 ** -24 && halfToFloat(0x7c00) === Infinity &&
	      Number.isNaN(halfToFloat(0x7e00)), 'half floats: known values');

	// OpenEXR
	const next = random(1234);
	const w = 7;
	const hgt = 5;
	const px = new Uint16Array(w * hgt * 4);
	for (let i = 0; i < px.length; i++)
		px[i] = next() & 0x7bff;
	const exrBytes = encodeExr(w, hgt, px);
	let exr = null;
	try {
		exr = parseExr(Buffer.from(exrBytes));
	} catch (e) {
		check(false, 'the EXR parses', e.message);
	}
	if (exr) {
		check(exr.channels.map((c) => c.name).join('') === 'ABGR', 'EXR channels sorted A, B, G, R');
		check(exr.width === w && exr.height === hgt, 'EXR data window of the image');
		let same = true;
		for (let p = 0; p < w * hgt; p++)
			['R', 'G', 'B', 'A'].forEach((c, k) => {
				same = same && exr.planes[c][p] === px[4 * p + k];
			});
		check(same, 'EXR pixels are the half floats given, bit for bit');
	}
	throws(() => encodeExr(w, hgt, px.subarray(4)), /values for/, 'EXR: too few values refused');

	// PNG
	const rgba = new Uint8ClampedArray(13 * 7 * 4);
	for (let i = 0; i < rgba.length; i++)
		rgba[i] = next() & 0xff;
	const blob = await encodePng(13, 7, rgba);
	const png = Buffer.from(await blob.arrayBuffer());
	let dec = null;
	try {
		dec = decodePng(png);
	} catch (e) {
		check(false, 'the PNG decodes', e.message);
	}
	if (dec) {
		check(dec.width === 13 && dec.height === 7 && dec.channels === 4 &&
		      Buffer.compare(dec.pixels, Buffer.from(rgba.buffer)) === 0,
		      'PNG: every byte back, partial alpha included');
	}
	check(blob.type === 'image/png', 'PNG blob type');
	check(crc32(Buffer.from('IEND')) === 0xae426082, 'the reference CRC-32 of IEND');

	// Sliders and numbers
	const eq = (a, b) => JSON.stringify(a) === JSON.stringify(b);
	const big = 9.999999843067494e+17;
	check(eq(sliderRange({min: 0, max: Math.PI}, 0.45), [0, Math.PI]), 'a cone angle: [0, pi]');
	check(eq(sliderRange({min: -big, max: big}, 60), [0, 240]), 'an unbounded intensity 60: [0, 240]');
	check(eq(sliderRange({min: -big, max: big}, -1), [-4, 0]), 'an unbounded -1: [-4, 0]');
	check(eq(sliderRange({min: -big, max: big}, 0), [0, 1]), 'an unbounded 0: [0, 1]');
	check(eq(sliderRange({min: 1, max: 1024}, 16), [1, 1024]), 'samples: [1, 1024]');
	check(eq(sliderRange({min: 0.5, max: big}, 2), [0.5, 8]), 'a lower bound is kept');
	check(formatNumber(0.07999999821186066) === '0.08' && formatNumber(60) === '60' &&
	      formatNumber(3.1415927410125732) === '3.14159', 'numbers shown without float noise');

	console.log(`${NAME}: ${n} checks, ${failed} failed`);
	process.exit(failed ? 1 : 0);
}

main().catch((e) => {
	console.error(`${NAME}: ${e && e.stack ? e.stack : e}`);
	process.exit(1);
});
