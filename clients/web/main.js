// The relight viewer: shows a shot's image as relightd refines it and edits
// its lights. See README.md in this folder.

import {ClosedError, Connection, FORMAT_RGBA16F, FORMAT_RGBA8, ServerError, socketUrl} from './protocol.js';
import {DEFAULT_GAMMA, Picture} from './image.js';
import {LightPanel, formatNumber} from './controls.js';
import {canEncodePng, download, encodeExr, encodePng} from './files.js';

// The token lives for the tab's session only (sessionStorage), never longer.
const TOKEN_KEY = 'relight.token';
const BACKOFF_MIN_MS = 500;
const BACKOFF_MAX_MS = 5000;
const EXR_TIMEOUT_MS = 60000;

// Codes that mean this page and the daemon do not understand each other:
// shown in the banner rather than the status line.
const PROTOCOL_CODES = new Set(['malformed', 'unknown_op', 'type', 'limit', 'internal']);

const $ = (id) => document.getElementById(id);

function now() {
	return performance.now();
}

// The final level of the newest edit of `shot`, as rgba16f half floats, over
// a connection of its own (the display's stays in rgba8).
async function grabHalfImage(url, token, shot) {
	let width = 0;
	let height = 0;
	let levels = 4;
	let half = null;
	let edit = -1;
	let opened = false;
	let covered = 0;
	const seen = new Set();
	let done;
	let fail;
	const finished = new Promise((resolve, reject) => {
		done = resolve;
		fail = reject;
	});
	const conn = new Connection(url, {
		token,
		onTile: (t) => {
			if (!opened || t.format !== FORMAT_RGBA16F || t.edit < edit ||
			    t.x + t.width > width || t.y + t.height > height)
				return;
			if (t.edit > edit) {
				edit = t.edit;
				seen.clear();
				covered = 0;
			}
			if (t.level !== levels - 1)
				return;
			const key = `${t.x},${t.y}`;
			if (!seen.has(key)) {
				seen.add(key);
				covered += t.width * t.height;
			}
			for (let r = 0; r < t.height; r++)
				half.set(t.pixels.subarray(r * t.width * 4, (r + 1) * t.width * 4),
					 ((t.y + r) * width + t.x) * 4);
		},
		onMessage: (m) => {
			if (m.op === 'level' && opened && m.edit === edit && m.level === levels - 1 &&
			    covered === width * height)
				done(edit);
		},
		onClose: (code, reason) => fail(new ClosedError(code, reason)),
	});
	const timer = setTimeout(() => fail(new Error(
		`no final level in rgba16f within ${EXR_TIMEOUT_MS / 1000} s`)), EXR_TIMEOUT_MS);
	try {
		await conn.connect();
		const o = await conn.request('open', {shot, format: 'rgba16f'});
		width = o.width;
		height = o.height;
		levels = o.levels;
		edit = o.edit;
		half = new Uint16Array(width * height * 4);
		opened = true;
		const e = await finished;
		return {width, height, edit: e, half};
	} finally {
		clearTimeout(timer);
		conn.close();
	}
}

class Viewer {
	constructor() {
		this.url = socketUrl();
		this.picture = new Picture($('image'));
		this.panel = new LightPanel($('light-list'), {
			onParam: (light, name, value) => this.queueParam(light, name, value),
			onSolo: (light) => this.edit('solo', {light}, () => this.panel.setSolo(light)),
			onMute: (light, on) => this.edit('mute', {light, mute: on},
							 () => this.panel.setMuted(light, on)),
			onFreeze: (light, on) => this.edit('freeze', {light, freeze: on},
							   () => this.panel.setFrozen(light, on)),
			onRemove: (light) => this.edit('remove_light', {light}, () => this.reopen()),
		});
		this.conn = null;
		this.token = '';
		this.shot = null;          // the shot wanted
		this.opened = null;        // its "opened" reply
		this.lastShot = null;      // the shot the picture shows
		this.role = null;
		this.phase = 'idle';       // connecting, connected, open, disconnected, auth, error
		this.everConnected = false;
		this.newestEdit = -1;      // newest edit seen: acked, in a level message or a tile
		this.ackedEdit = -1;
		this.level = -1;           // level reached by newestEdit
		this.timings = new Map();  // edit -> {sent, firstTile, final} (performance.now)
		this.latency = null;       // {edit, firstTileMs, finalMs} of the newest edit timed
		this.pending = new Map();  // light -> params not sent yet
		this.inFlight = null;      // the one "set" sent and not answered
		this.flushScheduled = false;
		this.counters = {editsSent: 0, tilesDrawn: 0, tilesDropped: 0, badTiles: 0, reconnects: 0};
		this.backoff = BACKOFF_MIN_MS;
		this.retryTimer = null;
		this.retryAt = 0;
		this.countdown = null;
		this.banner = null;
		this.message = '';
		this.pick = null;
		this.pickNote = null;
		this.pickUnsupported = false;
		this.pickTimer = null;
		this.exporting = false;
		this.statusScheduled = false;
		this.bind();
	}

	// ---- the page ----

	bind() {
		$('image').addEventListener('click', (ev) => this.pickAt(ev.clientX, ev.clientY));
		const exposure = $('exposure');
		const exposureNum = $('exposure-num');
		const gamma = $('gamma');
		const gammaNum = $('gamma-num');
		const display = (stops, g) => {
			if (!Number.isFinite(stops) || !Number.isFinite(g) || g <= 0)
				return;
			exposure.value = String(stops);
			gamma.value = String(g);
			if (document.activeElement !== exposureNum)
				exposureNum.value = formatNumber(stops);
			if (document.activeElement !== gammaNum)
				gammaNum.value = formatNumber(g);
			this.picture.setDisplay(stops, g);
			this.updateStatus();
		};
		exposure.addEventListener('input', () => display(exposure.valueAsNumber, this.picture.gamma));
		exposureNum.addEventListener('input', () => display(exposureNum.valueAsNumber, this.picture.gamma));
		gamma.addEventListener('input', () => display(this.picture.stops, gamma.valueAsNumber));
		gammaNum.addEventListener('input', () => display(this.picture.stops, gammaNum.valueAsNumber));
		$('display-reset').addEventListener('click', () => {
			display(0, DEFAULT_GAMMA);
			exposureNum.value = '0';
			gammaNum.value = String(DEFAULT_GAMMA);
		});
		$('save-png').addEventListener('click', () => this.savePng());
		$('save-exr').addEventListener('click', () => this.saveExr());
		$('shot-select').addEventListener('change', (ev) => {
			if (ev.target.value)
				this.chooseShot(ev.target.value);
		});
		$('banner-retry').addEventListener('click', () => this.connect());
		$('connect-form').addEventListener('submit', (ev) => {
			ev.preventDefault();
			this.submitDialog();
		});
		$('connect-cancel').addEventListener('click', () => $('connect-dialog').close());
		$('add-light').addEventListener('submit', (ev) => {
			ev.preventDefault();
			this.addLight();
		});
		$('pick-info').addEventListener('click', () => this.clearPick());
		// The ring would no longer be on its pixel.
		window.addEventListener('resize', () => {
			$('pick-mark').hidden = true;
		});
		if (typeof ResizeObserver === 'function')
			new ResizeObserver(() => this.fit()).observe($('image').parentElement);
	}

	start() {
		const q = new URLSearchParams(window.location.search);
		const token = q.get('token');
		if (token !== null) {
			// Out of the address bar and the history it would be copied from.
			sessionStorage.setItem(TOKEN_KEY, token);
			q.delete('token');
			this.replaceQuery(q);
		}
		this.token = sessionStorage.getItem(TOKEN_KEY) || '';
		this.shot = q.get('shot') || null;
		this.connect();
	}

	replaceQuery(q) {
		const s = q.toString();
		history.replaceState(null, '', window.location.pathname + (s ? '?' + s : '') + window.location.hash);
	}

	setBanner(kind, text, retry = false) {
		this.banner = kind ? {kind, text} : null;
		const b = $('banner');
		b.hidden = !kind;
		b.className = kind ? `banner ${kind}` : 'banner';
		$('banner-text').textContent = text || '';
		$('banner-retry').hidden = !retry;
	}

	say(text) {
		this.message = text;
		this.updateStatus();
	}

	showDialog(note) {
		const d = $('connect-dialog');
		$('connect-note').textContent = note || '';
		$('connect-token').value = this.token;
		$('connect-shot').value = this.shot || '';
		if (!d.open)
			d.showModal();
		(this.phase === 'auth' ? $('connect-token') : $('connect-shot')).focus();
	}

	submitDialog() {
		const token = $('connect-token').value.trim();
		const shot = $('connect-shot').value.trim();
		$('connect-dialog').close();
		const newToken = token !== this.token;
		this.token = token;
		if (token)
			sessionStorage.setItem(TOKEN_KEY, token);
		else
			sessionStorage.removeItem(TOKEN_KEY);
		if (shot)
			this.setShotParam(shot);
		this.shot = shot || this.shot;
		if (newToken || !this.conn || !this.conn.open)
			this.connect();
		else if (this.shot)
			this.openShot(this.shot);
	}

	setShotParam(shot) {
		const q = new URLSearchParams(window.location.search);
		q.set('shot', shot);
		this.replaceQuery(q);
	}

	chooseShot(shot) {
		this.shot = shot;
		this.setShotParam(shot);
		if (this.conn && this.conn.open)
			this.openShot(shot);
	}

	// ---- the connection ----

	connect() {
		clearTimeout(this.retryTimer);
		clearInterval(this.countdown);
		this.retryTimer = null;
		if (this.conn)
			this.conn.close();
		const conn = new Connection(this.url, {
			token: this.token,
			onMessage: (m) => this.onMessage(conn, m),
			onTile: (t) => this.onTile(conn, t),
			onBadTile: (e) => {
				this.counters.badTiles++;
				this.say(`bad tile: ${e.message}`);
			},
			onClose: (code, reason) => this.onClose(conn, code, reason),
		});
		this.conn = conn;
		this.opened = null;
		this.inFlight = null;
		this.setPhase('connecting');
		conn.connect().then((h) => this.onHello(conn, h), (e) => this.onConnectFailed(conn, e));
	}

	// A small image is zoomed by a whole factor to fill the view; a large
	// one is scaled down to fit (by the stylesheet's max-width/max-height).
	fit() {
		const canvas = $('image');
		const box = canvas.parentElement;
		const w = this.picture.width;
		const h = this.picture.height;
		if (!w || !h)
			return;
		const style = getComputedStyle(box);
		const availW = box.clientWidth - parseFloat(style.paddingLeft) - parseFloat(style.paddingRight);
		const availH = box.clientHeight - parseFloat(style.paddingTop) - parseFloat(style.paddingBottom);
		const zoom = Math.floor(Math.min(availW / w, availH / h));
		if (zoom >= 2) {
			canvas.classList.add('zoomed');
			canvas.style.width = `${w * zoom}px`;
			canvas.style.height = `${h * zoom}px`;
		} else {
			canvas.classList.remove('zoomed');
			canvas.style.width = '';
			canvas.style.height = '';
		}
	}

	setPhase(phase) {
		this.phase = phase;
		document.body.dataset.phase = phase;
		this.updateStatus();
	}

	onHello(conn, hello) {
		if (conn !== this.conn)
			return;
		if (this.everConnected)
			this.counters.reconnects++;
		this.everConnected = true;
		this.backoff = BACKOFF_MIN_MS;
		this.role = hello.role === 'viewer' ? 'viewer' : 'editor';
		this.pickUnsupported = false;
		this.setBanner(null);
		this.setPhase('connected');
		const ro = this.role === 'viewer';
		this.panel.setReadOnly(ro);
		$('role-badge').hidden = !ro;
		$('add-light-fields').disabled = ro;
		document.body.classList.toggle('read-only', ro);
		$('server-name').textContent = `${hello.server || 'relightd'}${hello.gpu ? ' on ' + hello.gpu : ''}`;
		conn.request('list').then((r) => this.showShots(r.shots || []),
			(e) => this.requestFailed('list', e));
		if (this.shot)
			this.openShot(this.shot);
		else
			this.showDialog('Choose a shot.');
	}

	onConnectFailed(conn, e) {
		if (conn !== this.conn)
			return;
		conn.close();
		if (e instanceof ServerError) {
			// A refused token or a daemon of another protocol version: trying
			// again would only be refused again.
			if (e.code === 'auth') {
				this.setPhase('auth');
				this.setBanner('error', `Not admitted: ${e.code}: ${e.serverMessage}`, true);
				this.showDialog(`relightd refused the token (${e.serverMessage}).`);
			} else {
				this.setPhase('error');
				this.setBanner('error', `Protocol error: ${e.code}: ${e.serverMessage}`, true);
			}
			return;
		}
		this.scheduleReconnect(e instanceof ClosedError ? e.code : 0,
			e instanceof ClosedError ? e.reason : e.message);
	}

	onClose(conn, code, reason) {
		if (conn !== this.conn)
			return;
		// A set in flight is put back in the queue by its request's failure.
		this.scheduleReconnect(code, reason);
	}

	scheduleReconnect(code, reason) {
		this.setPhase('disconnected');
		const delay = this.backoff;
		this.backoff = Math.min(BACKOFF_MAX_MS, this.backoff * 2);
		this.retryAt = now() + delay;
		const what = `${this.everConnected ? 'Connection to relightd lost' : 'Cannot reach relightd'}` +
			`${code ? ` (${code}${reason ? ': ' + reason : ''})` : ''}`;
		const tick = () => {
			const s = Math.max(0, (this.retryAt - now()) / 1000);
			this.setBanner('warn', `${what}: reconnecting in ${s.toFixed(1)} s`, true);
		};
		tick();
		clearInterval(this.countdown);
		this.countdown = setInterval(tick, 100);
		clearTimeout(this.retryTimer);
		this.retryTimer = setTimeout(() => {
			clearInterval(this.countdown);
			this.setBanner('warn', `${what}: reconnecting`, true);
			this.connect();
		}, delay);
	}

	showShots(shots) {
		const sel = $('shot-select');
		const list = $('shot-list');
		sel.replaceChildren(new Option('choose a shot', ''));
		list.replaceChildren();
		for (const s of shots) {
			const label = `${s.name} (${s.width}\u00d7${s.height}${s.baked === false ? ', not baked' : ''})`;
			sel.append(new Option(label, s.name));
			list.append(new Option(label, s.name));
		}
		sel.value = this.shot || '';
	}

	openShot(shot) {
		const conn = this.conn;
		this.opened = null;
		this.setPhase('connected');
		this.say(`opening ${shot}`);
		conn.request('open', {shot, format: 'rgba8'}).then((o) => this.onOpened(conn, o), (e) => {
			if (conn !== this.conn || e instanceof ClosedError)
				return;
			if (e instanceof ServerError && e.code === 'unknown_shot') {
				this.setBanner('error', `${e.code}: ${e.serverMessage}`);
				this.showDialog(`No shot '${shot}' here: choose another.`);
			} else {
				this.requestFailed('open', e);
			}
		});
	}

	// Opens the shot again, for the light list after a light was added or removed.
	reopen() {
		if (this.conn && this.conn.open && this.shot)
			this.openShot(this.shot);
	}

	onOpened(conn, o) {
		if (conn !== this.conn)
			return;
		const same = this.picture.width === o.width && this.picture.height === o.height &&
			this.lastShot === o.shot;
		if (!same) {
			this.picture.reset(o.width, o.height);
			this.fit();
		}
		if (this.lastShot !== o.shot || o.edit < this.newestEdit) {
			// Another shot, or a daemon started again: its edits count anew,
			// and no light is muted, soloed or frozen by this page.
			this.timings.clear();
			this.latency = null;
			this.panel.resetToggles();
			if (this.lastShot !== o.shot)
				this.pending.clear();
		}
		this.lastShot = o.shot;
		this.opened = o;
		this.shot = o.shot;
		this.newestEdit = o.edit;
		this.ackedEdit = o.edit;
		this.level = -1;
		this.panel.setLights(o.lights || []);
		// Newer daemons may say which lights are muted, frozen or soloed.
		if ('solo' in o)
			this.panel.setSolo(typeof o.solo === 'string' ? o.solo : null);
		for (const l of o.lights || []) {
			if (typeof l.muted === 'boolean')
				this.panel.setMuted(l.name, l.muted);
			if (typeof l.frozen === 'boolean')
				this.panel.setFrozen(l.name, l.frozen);
		}
		$('shot-select').value = o.shot;
		document.title = `${o.shot} \u2014 relight`;
		$('add-light-name').placeholder = this.freeLightName();
		const shaders = $('shader-list');
		shaders.replaceChildren();
		for (const s of new Set([...this.panel.shaders(), 'ambientlight', 'distantlight',
					 'pointlight', 'spotlight', 'shadowspot']))
			shaders.append(new Option(s, s));
		if ($('connect-dialog').open)
			$('connect-dialog').close();
		if (this.banner && this.banner.kind === 'error')
			this.setBanner(null);
		this.message = '';
		this.setPhase('open');
		this.scheduleFlush();
	}

	freeLightName() {
		const names = new Set((this.opened ? this.opened.lights : []).map((l) => l.name));
		for (let i = names.size + 1; ; i++)
			if (!names.has(`L${i}`))
				return `L${i}`;
	}

	onMessage(conn, m) {
		if (conn !== this.conn)
			return;
		switch (m.op) {
		case 'level':
			this.onLevel(m);
			break;
		case 'progress':
			this.say(`baking ${m.shot}: ${Math.round(100 * (m.fraction || 0))}%${m.what ? ' (' + m.what + ')' : ''}`);
			break;
		case 'error':
			this.serverError(m.code, m.message, m.op);
			break;
		default:
			break;
		}
	}

	onLevel(m) {
		if (!this.opened || (typeof m.shot === 'string' && m.shot !== this.opened.shot))
			return;
		if (!Number.isInteger(m.edit) || !Number.isInteger(m.level) || m.edit < this.newestEdit)
			return;
		if (m.edit > this.newestEdit) {
			this.newestEdit = m.edit;
			this.level = -1;
		}
		this.level = Math.max(this.level, m.level);
		if (m.level === this.opened.levels - 1) {
			const t = this.timings.get(m.edit);
			if (t && t.final === null) {
				t.final = now();
				this.measured(m.edit);
			}
		}
		this.updateStatus();
	}

	onTile(conn, t) {
		if (conn !== this.conn)
			return;
		// Tiles of an edit older than the newest seen are superseded; and
		// between an open and its reply they may be the last shot's.
		if (!this.opened || t.format !== FORMAT_RGBA8 || t.edit < this.newestEdit) {
			this.counters.tilesDropped++;
			return;
		}
		if (t.edit > this.newestEdit) {
			this.newestEdit = t.edit;
			this.level = -1;
		}
		if (!this.picture.putTile(t)) {
			this.counters.tilesDropped++;
			return;
		}
		this.counters.tilesDrawn++;
		let timing = this.timings.get(t.edit);
		if (!timing) {
			// A tile before its ack, or another editor's edit: kept until
			// the ack says when it was sent.
			timing = {sent: null, firstTile: now(), final: null};
			this.timings.set(t.edit, timing);
			this.trimTimings();
		} else if (timing.firstTile === null) {
			timing.firstTile = now();
			this.measured(t.edit);
		}
		this.updateStatus();
	}

	trimTimings() {
		while (this.timings.size > 64)
			this.timings.delete(this.timings.keys().next().value);
	}

	measured(edit) {
		const t = this.timings.get(edit);
		if (!t || t.sent === null)
			return;
		this.latency = {
			edit,
			firstTileMs: t.firstTile === null ? null : t.firstTile - t.sent,
			finalMs: t.final === null ? null : t.final - t.sent,
		};
	}

	serverError(code, message, op) {
		if (code === 'auth' || PROTOCOL_CODES.has(code))
			this.setBanner('error', `${op ? op + ': ' : ''}${code}: ${message}`);
		else
			this.say(`${code}: ${message}`);
	}

	requestFailed(op, e) {
		if (e instanceof ClosedError)
			return;
		if (e instanceof ServerError)
			this.serverError(e.code, e.serverMessage, op);
		else
			this.say(`${op}: ${e.message}`);
	}

	// ---- edits ----

	canEdit() {
		return this.role === 'editor' && this.conn && this.conn.open && this.opened;
	}

	// A parameter moved: merged into the edit waiting for its light.
	queueParam(light, name, value) {
		if (this.role !== 'editor')
			return;
		let p = this.pending.get(light);
		if (!p) {
			p = {};
			this.pending.set(light, p);
		}
		p[name] = value;
		this.scheduleFlush();
	}

	// A set that did not arrive goes back in the queue, under newer values.
	requeue(light, params) {
		const p = this.pending.get(light) || {};
		this.pending.set(light, Object.assign({}, params, p));
	}

	// At most one set in flight, and at most one sent an animation frame:
	// a drag sends the newest value once the last one is acknowledged.
	scheduleFlush() {
		if (this.flushScheduled || this.inFlight || !this.pending.size)
			return;
		this.flushScheduled = true;
		const run = () => {
			this.flushScheduled = false;
			this.flush();
		};
		if (document.hidden)
			setTimeout(run, 16);
		else
			requestAnimationFrame(run);
	}

	flush() {
		if (this.inFlight || !this.pending.size || !this.canEdit())
			return;
		const [light, params] = this.pending.entries().next().value;
		this.pending.delete(light);
		this.inFlight = {light, params};
		this.edit('set', {light, params}, null, () => {
			this.inFlight = null;
			this.scheduleFlush();
		});
	}

	// Sends an edit; `then` runs on its ack, `always` once it is answered.
	edit(op, fields, then = null, always = null) {
		if (!this.canEdit()) {
			if (always)
				always();
			return;
		}
		const conn = this.conn;
		const sent = now();
		this.counters.editsSent++;
		conn.request(op, fields).then((ack) => {
			if (conn !== this.conn)
				return;
			this.onAck(op, ack, sent);
			if (then)
				then(ack);
		}, (e) => {
			if (conn !== this.conn)
				return;
			if (op === 'set' && e instanceof ClosedError)
				this.requeue(fields.light, fields.params);
			this.requestFailed(op, e);
		}).finally(() => {
			if (always && conn === this.conn)
				always();
		});
	}

	onAck(op, ack, sent) {
		const e = ack.edit;
		if (!Number.isInteger(e))
			return;
		this.ackedEdit = Math.max(this.ackedEdit, e);
		// A freeze changes no pixel: its ack names the current edit, and no
		// tiles follow.
		if (op === 'freeze')
			return;
		if (e > this.newestEdit) {
			this.newestEdit = e;
			this.level = -1;
		}
		const t = this.timings.get(e);
		if (t)
			t.sent = sent;
		else
			this.timings.set(e, {sent, firstTile: null, final: null});
		this.trimTimings();
		this.measured(e);
		this.updateStatus();
	}

	addLight() {
		const shader = $('add-light-shader').value.trim();
		const name = $('add-light-name').value.trim() || this.freeLightName();
		if (!shader) {
			$('add-light-shader').focus();
			this.say('add light: name a light shader');
			return;
		}
		this.edit('add_light', {light: name, shader, params: {}}, () => {
			$('add-light-name').value = '';
			this.reopen();
		});
	}

	// ---- picking ----

	pickAt(clientX, clientY) {
		if (!this.opened || !this.conn || !this.conn.open)
			return;
		const p = this.picture.pixelAt(clientX, clientY);
		if (!p)
			return;
		if (this.pickUnsupported) {
			this.showPickNote();
			return;
		}
		this.markPick(clientX, clientY);
		const conn = this.conn;
		conn.request('pick', {x: p.x, y: p.y}).then((r) => {
			if (conn !== this.conn)
				return;
			this.pick = {x: r.x, y: r.y, object: r.object === undefined ? null : r.object,
				     lights: Array.isArray(r.lights) ? r.lights : []};
			this.pickNote = null;
			const what = this.pick.object === null ? 'background' : `object ${this.pick.object}`;
			const lights = this.pick.lights.length ? `lit by ${this.pick.lights.join(', ')}` : 'no light reaches it';
			this.showPickInfo(`${this.pick.x}, ${this.pick.y}: ${what}; ${lights}`);
			this.panel.highlight(this.pick.lights);
		}, (e) => {
			if (conn !== this.conn)
				return;
			if (e instanceof ServerError && e.code === 'unknown_op') {
				this.pickUnsupported = true;
				this.showPickNote();
			} else {
				this.requestFailed('pick', e);
			}
		});
	}

	// A ring where the image was clicked, until the pick is dismissed.
	markPick(clientX, clientY) {
		const mark = $('pick-mark');
		const r = $('image').parentElement.getBoundingClientRect();
		mark.style.left = `${clientX - r.left}px`;
		mark.style.top = `${clientY - r.top}px`;
		mark.hidden = false;
	}

	showPickNote() {
		this.pickNote = 'picking needs a newer relightd';
		this.showPickInfo(this.pickNote, true);
	}

	showPickInfo(text, note = false) {
		const box = $('pick-info');
		box.textContent = text;
		box.classList.toggle('note', note);
		box.hidden = false;
		clearTimeout(this.pickTimer);
		if (note)
			this.pickTimer = setTimeout(() => this.clearPick(), 4000);
	}

	clearPick() {
		$('pick-info').hidden = true;
		$('pick-mark').hidden = true;
		this.panel.highlight(null);
	}

	// ---- files ----

	fileName(ext) {
		return `${this.opened ? this.opened.shot : 'relight'}-e${this.newestEdit}.${ext}`;
	}

	async savePng() {
		if (!this.opened)
			return;
		const {width, height, raw} = this.picture;
		let blob;
		if (canEncodePng()) {
			blob = await encodePng(width, height, raw);
		} else {
			// No CompressionStream: the canvas's encoder, which is exact where
			// alpha is 0 or 255 only.
			const c = document.createElement('canvas');
			c.width = width;
			c.height = height;
			c.getContext('2d').putImageData(new ImageData(new Uint8ClampedArray(raw), width, height), 0, 0);
			blob = await new Promise((resolve) => c.toBlob(resolve, 'image/png'));
		}
		download(blob, this.fileName('png'));
		this.say(`saved ${this.fileName('png')}`);
	}

	async saveExr() {
		if (!this.opened || this.exporting)
			return;
		this.exporting = true;
		const button = $('save-exr');
		button.disabled = true;
		this.say('EXR: waiting for the final level in half floats');
		try {
			const img = await grabHalfImage(this.url, this.token, this.opened.shot);
			const name = `${this.opened.shot}-e${img.edit}.exr`;
			download(new Blob([encodeExr(img.width, img.height, img.half)], {type: 'image/x-exr'}), name);
			this.say(`saved ${name}`);
		} catch (e) {
			this.say(`EXR: ${e.message}`);
		} finally {
			this.exporting = false;
			button.disabled = false;
		}
	}

	// ---- status ----

	updateStatus() {
		if (this.statusScheduled)
			return;
		this.statusScheduled = true;
		const run = () => {
			this.statusScheduled = false;
			this.renderStatus();
		};
		if (document.hidden)
			setTimeout(run, 50);
		else
			requestAnimationFrame(run);
	}

	renderStatus() {
		const parts = [];
		const conn = {connecting: 'connecting', connected: 'connected', open: 'connected',
			      disconnected: 'disconnected', auth: 'not admitted', error: 'error', idle: ''}[this.phase];
		$('conn-state').textContent = conn;
		$('conn-state').dataset.phase = this.phase;
		if (this.opened) {
			const o = this.opened;
			const last = o.levels - 1;
			parts.push(`${o.shot} ${o.width}\u00d7${o.height}`);
			parts.push(`edit ${this.newestEdit}`);
			parts.push(this.level < 0 ? 'level \u2013' :
				`level ${this.level}/${last}${this.level === last ? ' final' : ''}`);
			if (this.latency) {
				const ms = (v) => (v === null ? '\u2026' : `${v.toFixed(1)} ms`);
				parts.push(`edit ${this.latency.edit} \u2192 first tile ${ms(this.latency.firstTileMs)}, ` +
					   `\u2192 final ${ms(this.latency.finalMs)}`);
			}
			if (this.picture.stops !== 0 || this.picture.gamma !== DEFAULT_GAMMA)
				parts.push(`display ${this.picture.stops >= 0 ? '+' : ''}${formatNumber(this.picture.stops)} EV, ` +
					   `\u03b3 ${formatNumber(this.picture.gamma)}`);
		}
		$('status-main').textContent = parts.join(' \u00b7 ');
		$('status-message').textContent = this.message;
		const ready = this.opened !== null;
		$('save-png').disabled = !ready;
		$('save-exr').disabled = !ready || this.exporting;
	}

	// What the page shows, for scripts and tests (window.relightViewer.state).
	get state() {
		const o = this.opened;
		return {
			phase: this.phase,
			connected: Boolean(this.conn && this.conn.open),
			role: this.role,
			shot: o ? o.shot : null,
			width: o ? o.width : 0,
			height: o ? o.height : 0,
			levels: o ? o.levels : 0,
			edit: this.newestEdit,
			ackedEdit: this.ackedEdit,
			level: this.level,
			final: Boolean(o && this.level === o.levels - 1),
			pendingEdits: this.pending.size + (this.inFlight ? 1 : 0),
			latency: this.latency ? Object.assign({}, this.latency) : null,
			banner: this.banner ? Object.assign({}, this.banner) : null,
			pick: this.pick ? Object.assign({}, this.pick) : null,
			pickNote: this.pickNote,
			stops: this.picture.stops,
			gamma: this.picture.gamma,
			editsSent: this.counters.editsSent,
			tilesDrawn: this.counters.tilesDrawn,
			tilesDropped: this.counters.tilesDropped,
			badTiles: this.counters.badTiles,
			reconnects: this.counters.reconnects,
			message: this.message,
		};
	}
}

const viewer = new Viewer();
window.relightViewer = viewer;
viewer.start();
