// The relight protocol, version 1 (protocol/README.md), as the browser
// speaks it: one WebSocket with JSON text frames for requests and replies,
// and binary tile frames for the image.

export const SUBPROTOCOL = 'relight.v1';
export const VERSION = 1;
export const TILE_HEADER_SIZE = 36;
export const FORMAT_RGBA8 = 1;
export const FORMAT_RGBA16F = 2;

// The browsers this runs in are little-endian; the check keeps a big-endian
// one correct, on a slower path.
const LITTLE_ENDIAN = new Uint8Array(new Uint16Array([1]).buffer)[0] === 1;

// An {"op":"error"} reply, or a refusal in the same terms.
export class ServerError extends Error {
	constructor(code, message, reply = null) {
		super(`${code}: ${message}`);
		this.code = code;
		this.serverMessage = message;
		this.reply = reply;
	}
}

// The connection closed before the reply came.
export class ClosedError extends Error {
	constructor(code, reason) {
		super(`connection closed (${code}${reason ? ': ' + reason : ''})`);
		this.code = code;
		this.reason = reason;
	}
}

// The WebSocket URL of the daemon that served this page: same host and
// port, wss:// under https://.
export function socketUrl(loc = window.location) {
	const scheme = loc.protocol === 'https:' ? 'wss:' : 'ws:';
	return `${scheme}//${loc.host}/ws`;
}

// One tile frame: {edit, level, format, x, y, width, height, pixels}, with
// pixels a Uint8Array (rgba8) or a Uint16Array of half floats (rgba16f)
// over the frame's buffer. Throws an Error naming what is wrong.
export function parseTile(buffer) {
	const n = buffer.byteLength;
	if (n < TILE_HEADER_SIZE)
		throw new Error(`tile frame of ${n} bytes, shorter than its ${TILE_HEADER_SIZE}-byte header`);
	const b = new Uint8Array(buffer, 0, 4);
	if (b[0] !== 0x52 || b[1] !== 0x4c || b[2] !== 0x54 || b[3] !== 0x31)
		throw new Error('binary frame without the tile magic RLT1');
	const v = new DataView(buffer);
	const header = v.getUint32(4, true);
	if (header !== TILE_HEADER_SIZE)
		throw new Error(`tile header size ${header}, expected ${TILE_HEADER_SIZE}`);
	const t = {
		edit: v.getUint32(8, true),
		level: v.getUint32(12, true),
		format: v.getUint32(16, true),
		x: v.getUint32(20, true),
		y: v.getUint32(24, true),
		width: v.getUint32(28, true),
		height: v.getUint32(32, true),
		pixels: null,
	};
	const bpp = t.format === FORMAT_RGBA8 ? 4 : t.format === FORMAT_RGBA16F ? 8 : 0;
	if (!bpp)
		throw new Error(`tile of unknown format ${t.format}`);
	const want = header + t.width * t.height * bpp;
	if (n !== want)
		throw new Error(`tile frame of ${n} bytes, its header says ${want}`);
	if (t.format === FORMAT_RGBA8) {
		t.pixels = new Uint8Array(buffer, header, t.width * t.height * 4);
	} else if (LITTLE_ENDIAN) {
		t.pixels = new Uint16Array(buffer, header, t.width * t.height * 4);
	} else {
		t.pixels = new Uint16Array(t.width * t.height * 4);
		for (let i = 0; i < t.pixels.length; i++)
			t.pixels[i] = v.getUint16(header + 2 * i, true);
	}
	return t;
}

// One WebSocket connection to relightd, after its hello.
//
//   const c = new Connection(url, {token, onMessage, onTile, onClose});
//   const hello = await c.connect();          // ServerError 'auth' on a bad token
//   const opened = await c.request('open', {shot: 'shadows', format: 'rgba8'});
//
// Replies complete the request with their id; everything else (level,
// progress, errors without an id) goes to onMessage, tiles to onTile (each
// already parsed; a frame that does not parse goes to onBadTile), and the
// end of the connection to onClose(code, reason) once.
export class Connection {
	constructor(url, {token = '', onMessage = null, onTile = null, onBadTile = null,
			  onClose = null, onSend = null} = {}) {
		this.url = url;
		this.token = token;
		this.onMessage = onMessage;
		this.onTile = onTile;
		this.onBadTile = onBadTile;
		this.onClose = onClose;
		this.onSend = onSend;
		this.ws = null;
		this.hello = null;
		this.nextId = 1;
		this.pending = new Map();
		this.closed = false;
	}

	// Opens the socket and says hello; resolves with the hello reply.
	connect(timeoutMs = 10000) {
		return new Promise((resolve, reject) => {
			let settled = false;
			const settle = (fn, arg) => {
				if (!settled) {
					settled = true;
					clearTimeout(timer);
					fn(arg);
				}
			};
			const timer = setTimeout(() => {
				settle(reject, new Error(`no hello from ${this.url} within ${timeoutMs / 1000} s`));
				this.close();
			}, timeoutMs);
			let ws;
			try {
				ws = new WebSocket(this.url, SUBPROTOCOL);
			} catch (e) {
				settle(reject, e);
				return;
			}
			ws.binaryType = 'arraybuffer';
			this.ws = ws;
			ws.onopen = () => {
				const hello = {op: 'hello', version: VERSION};
				if (this.token)
					hello.token = this.token;
				this.sendRaw(hello);
			};
			ws.onmessage = (ev) => {
				if (typeof ev.data !== 'string') {
					this.binary(ev.data);
					return;
				}
				let msg;
				try {
					msg = JSON.parse(ev.data);
				} catch (e) {
					this.dispatch({op: 'error', code: 'malformed',
						       message: `the daemon sent text that is not JSON: ${e.message}`});
					return;
				}
				if (!msg || typeof msg !== 'object')
					return;
				if (!this.hello) {
					// The first text frame answers the hello.
					if (msg.op === 'hello') {
						this.hello = msg;
						settle(resolve, msg);
					} else if (msg.op === 'error') {
						settle(reject, new ServerError(msg.code, msg.message, msg));
					} else {
						settle(reject, new ServerError('malformed',
							`expected a hello reply, got op '${msg.op}'`, msg));
					}
					return;
				}
				this.dispatch(msg);
			};
			ws.onclose = (ev) => {
				const wasClosed = this.closed;
				this.closed = true;
				const err = new ClosedError(ev.code, ev.reason);
				settle(reject, err);
				for (const p of this.pending.values())
					p.reject(err);
				this.pending.clear();
				if (!wasClosed && this.onClose)
					this.onClose(ev.code, ev.reason);
			};
			// An error event is always followed by close, which says the rest.
			ws.onerror = () => {};
		});
	}

	binary(buffer) {
		let tile;
		try {
			tile = parseTile(buffer);
		} catch (e) {
			if (this.onBadTile)
				this.onBadTile(e);
			return;
		}
		if (this.onTile)
			this.onTile(tile);
	}

	dispatch(msg) {
		const p = msg.op !== 'progress' && Number.isInteger(msg.id) ? this.pending.get(msg.id) : null;
		if (p) {
			this.pending.delete(msg.id);
			if (msg.op === 'error')
				p.reject(new ServerError(msg.code, msg.message, msg));
			else
				p.resolve(msg);
			return;
		}
		if (this.onMessage)
			this.onMessage(msg);
	}

	get open() {
		return !this.closed && this.ws !== null && this.ws.readyState === WebSocket.OPEN &&
			this.hello !== null;
	}

	sendRaw(obj) {
		if (!this.ws || this.ws.readyState !== WebSocket.OPEN)
			return false;
		this.ws.send(JSON.stringify(obj));
		if (this.onSend)
			this.onSend(obj);
		return true;
	}

	// Sends a request with a fresh id; resolves with its reply, rejects with
	// ServerError (an error reply) or ClosedError.
	request(op, fields = {}) {
		const id = this.nextId++;
		const msg = Object.assign({op, id}, fields);
		return new Promise((resolve, reject) => {
			if (!this.open) {
				reject(new ClosedError(1006, 'not connected'));
				return;
			}
			this.pending.set(id, {resolve, reject, op});
			this.sendRaw(msg);
		});
	}

	close(code = 1000, reason = '') {
		if (this.closed)
			return;
		this.closed = true;
		if (this.ws) {
			try {
				this.ws.close(code, reason);
			} catch (e) {
				// already closing
			}
		}
	}
}
