// The picture: the shot's image as tiles bring it, kept unadjusted, and
// shown in a canvas through the display transform (exposure and gamma).

// The sRGB transfer functions (IEC 61966-2-1), on values in [0, 1].
export function srgbToLinear(e) {
	return e <= 0.04045 ? e / 12.92 : Math.pow((e + 0.055) / 1.055, 2.4);
}

export function linearToSrgb(l) {
	if (!(l > 0))
		return 0;
	if (l >= 1)
		return 1;
	return l <= 0.0031308 ? 12.92 * l : 1.055 * Math.pow(l, 1 / 2.4) - 0.055;
}

// A half float (IEEE 754 binary16, as a 16-bit integer) as a number.
export function halfToFloat(h) {
	const s = h & 0x8000 ? -1 : 1;
	const e = (h >> 10) & 0x1f;
	const m = h & 0x3ff;
	if (e === 0)
		return s * m * Math.pow(2, -24);
	if (e === 31)
		return m ? NaN : s * Infinity;
	return s * (1 + m / 1024) * Math.pow(2, e - 15);
}

export const DEFAULT_GAMMA = 2.2;

// The display transform of an 8-bit sRGB value v, as a 256-entry table:
//
//   out = 255 * srgb( clamp( (lin(v / 255) * 2^stops) ^ (2.2 / gamma) ) )
//
// lin() decodes sRGB to linear, srgb() encodes it again, and the result is
// rounded. At 0 stops and gamma 2.2 the table is the identity (every 8-bit
// value survives the round trip exactly), so the canvas shows the daemon's
// pixels unchanged. Other gammas bend the curve around the sRGB one: overall
// the display is close to lin^(1 / gamma). Alpha is not transformed.
export function displayTable(stops, gamma) {
	const t = new Uint8Array(256);
	const identity = stops === 0 && gamma === DEFAULT_GAMMA;
	const gain = Math.pow(2, stops);
	const power = DEFAULT_GAMMA / gamma;
	for (let v = 0; v < 256; v++) {
		if (identity) {
			t[v] = v;
			continue;
		}
		const l = Math.pow(srgbToLinear(v / 255) * gain, power);
		t[v] = Math.round(255 * linearToSrgb(Math.min(1, l)));
	}
	return t;
}

// The image of one shot: `raw` holds the tiles' rgba8 pixels as they came
// (sRGB over black, then alpha); the canvas shows them through the display
// table with alpha 255, that is over black, as the colour already is.
export class Picture {
	constructor(canvas) {
		this.canvas = canvas;
		this.ctx = canvas.getContext('2d', {alpha: false, willReadFrequently: false});
		this.width = 0;
		this.height = 0;
		this.raw = new Uint8ClampedArray(0);
		this.table = displayTable(0, DEFAULT_GAMMA);
		this.stops = 0;
		this.gamma = DEFAULT_GAMMA;
	}

	// A new, black image of width x height.
	reset(width, height) {
		this.width = width;
		this.height = height;
		this.raw = new Uint8ClampedArray(width * height * 4);
		this.canvas.width = width;
		this.canvas.height = height;
		this.ctx.fillStyle = '#000';
		this.ctx.fillRect(0, 0, width, height);
	}

	// Copies an rgba8 tile into the image and draws it. False when it does
	// not fit the image (a tile of another shot).
	putTile(t) {
		if (t.x + t.width > this.width || t.y + t.height > this.height)
			return false;
		const rowBytes = t.width * 4;
		for (let r = 0; r < t.height; r++) {
			const src = t.pixels.subarray(r * rowBytes, (r + 1) * rowBytes);
			this.raw.set(src, ((t.y + r) * this.width + t.x) * 4);
		}
		this.draw(t.x, t.y, t.width, t.height);
		return true;
	}

	// Draws a rectangle of the image through the display table.
	draw(x, y, w, h) {
		if (w <= 0 || h <= 0)
			return;
		const img = new ImageData(w, h);
		const out = img.data;
		const table = this.table;
		for (let r = 0; r < h; r++) {
			let s = ((y + r) * this.width + x) * 4;
			let d = r * w * 4;
			for (let c = 0; c < w; c++, s += 4, d += 4) {
				out[d] = table[this.raw[s]];
				out[d + 1] = table[this.raw[s + 1]];
				out[d + 2] = table[this.raw[s + 2]];
				out[d + 3] = 255;
			}
		}
		this.ctx.putImageData(img, x, y);
	}

	setDisplay(stops, gamma) {
		this.stops = stops;
		this.gamma = gamma;
		this.table = displayTable(stops, gamma);
		this.draw(0, 0, this.width, this.height);
	}

	// The image pixel under a point of the page, or null outside it.
	pixelAt(clientX, clientY) {
		const r = this.canvas.getBoundingClientRect();
		if (!this.width || r.width <= 0 || r.height <= 0)
			return null;
		const x = Math.floor((clientX - r.left) * this.width / r.width);
		const y = Math.floor((clientY - r.top) * this.height / r.height);
		if (x < 0 || y < 0 || x >= this.width || y >= this.height)
			return null;
		return {x, y};
	}
}
