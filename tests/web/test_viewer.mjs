// The browser viewer (clients/web) in headless Chromium, driven by
// playwright-core, against relightd serving it with --viewer:
//
//   node test_viewer.mjs PATH/TO/relightd PATH/TO/relight
//
//   - load: /?token=…&shot=shadows reaches the final level; the token
//     leaves the address bar; the light list and its controls come from
//     the "opened" reply (a cone angle's slider spans [0, pi], an
//     intensity's 0 to 4 times its value); nothing is fetched from
//     anywhere but the daemon;
//   - edit: dragging light 2's intensity slider changes the image, sends
//     few edits (one in flight at a time), reaches the final level of the
//     newest one, shows its latency, and the canvas then equals, byte for
//     byte, the PNG `relight remote ... snapshot` writes of the same state;
//   - display: +1 stop changes the canvas to exactly the documented
//     transform of those pixels; reset gives them back unchanged;
//   - PNG download: equal to the daemon's PNG, alpha included;
//   - EXR download: a valid uncompressed scanline OpenEXR (magic, header
//     attributes, channels A B G R as HALF, data window, offsets), read by
//     the OpenEXR library (`relight diff`, exrheader) as identical to the
//     daemon's rgba16f snapshot, and within one 8-bit step of the PNG;
//   - pick: a click sends "pick"; the answer, or the note that the daemon
//     does not know the op yet, is shown;
//   - a viewer token: "view only" badge, controls disabled, no edit sent,
//     and the editor's edits shown all the same;
//   - a bad token: the banner names the auth error;
//   - the daemon stopped: the reconnect banner; started again on the same
//     port: the page reconnects by itself and shows the final level.
//
// Screenshots go to BUILD/web-artifacts. Exits 77 (skip), saying why, when
// node is too old, or playwright-core (scripts/setup installs it into
// tests/web/node_modules), Chromium or an EGL context is missing.

import {spawn, spawnSync} from 'node:child_process';
import {createRequire} from 'node:module';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {fileURLToPath} from 'node:url';
import {decodePng, displayed, halfToFloat, parseExr, srgb8} from './images.mjs';

const SKIP = 77;
const HERE = path.dirname(fileURLToPath(import.meta.url));
const SOURCE_DIR = process.env.RELIGHT_SOURCE_DIR || path.resolve(HERE, '..', '..');
const BUILD_DIR = process.env.RELIGHT_BUILD_DIR || path.join(os.tmpdir(), 'relight-web');
const ARTIFACTS = path.join(BUILD_DIR, 'web-artifacts');
const NAME = 'web-viewer';
const T0 = Date.now();

function skip(why) {
	// Said on both streams: a skip must not pass unnoticed.
	console.log(`SKIP: ${why}`);
	console.error(`${NAME}: SKIP: ${why}`);
	process.exit(SKIP);
}

function note(text) {
	console.log(`${NAME}: [${((Date.now() - T0) / 1000).toFixed(1)} s] ${text}`);
}

// ---------------------------------------------------------------------------
// Checks
// ---------------------------------------------------------------------------

const checks = {n: 0, failed: 0, section: ''};

function check(cond, what, detail = '') {
	checks.n++;
	if (!cond) {
		checks.failed++;
		console.error(`${NAME}: [${checks.section}] FAIL: ${what}${detail ? ` (${detail})` : ''}`);
	}
	return Boolean(cond);
}

async function section(name, fn) {
	checks.section = name;
	note(`${name}`);
	try {
		await fn();
	} catch (e) {
		check(false, `${name} threw`, e && e.stack ? e.stack.split('\n').slice(0, 6).join(' | ') : String(e));
	}
}

// ---------------------------------------------------------------------------
// The daemon and the relight command
// ---------------------------------------------------------------------------

function run(cmd, args, opts = {}) {
	const r = spawnSync(cmd, args, Object.assign({encoding: 'buffer', timeout: 120000,
		maxBuffer: 64 << 20}, opts));
	return {status: r.status, stdout: r.stdout ? r.stdout.toString() : '',
		stderr: r.stderr ? r.stderr.toString() : '', error: r.error};
}

// Daemons still running when the test ends early are killed on the way out.
const live = new Set();
process.on('exit', () => {
	for (const p of live)
		p.kill('SIGKILL');
});

class Daemon {
	constructor(relightd, opts) {
		this.relightd = relightd;
		this.opts = opts;
		this.proc = null;
		this.port = 0;
		this.exited = null;
	}

	// Starts it; resolves once it prints its listening line.
	async start(port = 0, attempts = 1) {
		for (let a = 1; ; a++) {
			const line = await this.spawn(port);
			if (line)
				return;
			const err = this.stderr();
			if (/EGL|GPU context/.test(err))
				skip(`relightd cannot get an EGL context: ${err.slice(0, 300)}`);
			// The port of the daemon just stopped may take a moment to free.
			if (a < attempts && /in use|bind/i.test(err)) {
				await sleep(500);
				continue;
			}
			throw new Error(`relightd did not start: ${err.slice(0, 1500)}`);
		}
	}

	spawn(port) {
		const o = this.opts;
		this.stderrPath = path.join(o.tmp, `relightd-${Date.now()}.stderr`);
		const errFd = fs.openSync(this.stderrPath, 'w');
		const args = ['--listen', `127.0.0.1:${port}`, '--shots', o.shots, '--snapshots', o.snapshots,
			      '--viewer', o.viewer];
		if (o.tokenFile)
			args.push('--token-file', o.tokenFile);
		const proc = spawn(this.relightd, args, {cwd: o.tmp, stdio: ['ignore', 'pipe', errFd]});
		this.proc = proc;
		fs.closeSync(errFd);
		live.add(proc);
		this.exited = new Promise((resolve) => proc.once('exit', (code, signal) => {
			live.delete(proc);
			resolve({code, signal});
		}));
		return new Promise((resolve) => {
			let text = '';
			const timer = setTimeout(() => done(null), 60000);
			const done = (line) => {
				clearTimeout(timer);
				this.proc.stdout.removeListener('data', onData);
				// Keep stdout drained.
				this.proc.stdout.on('data', () => {});
				resolve(line);
			};
			const onData = (b) => {
				text += b.toString();
				const nl = text.indexOf('\n');
				if (nl < 0)
					return;
				const line = text.slice(0, nl).trim();
				const m = /^relightd: listening on (https?):\/\/([^/]+)\/$/.exec(line);
				if (!m) {
					done(null);
					return;
				}
				this.port = Number(m[2].split(':').pop());
				this.base = `${m[1]}://127.0.0.1:${this.port}`;
				this.ws = `${m[1] === 'https' ? 'wss' : 'ws'}://127.0.0.1:${this.port}/ws`;
				done(line);
			};
			this.proc.stdout.on('data', onData);
			this.exited.then(() => done(null));
		});
	}

	stderr() {
		try {
			return fs.readFileSync(this.stderrPath, 'utf8');
		} catch (e) {
			return '';
		}
	}

	// SIGTERM; the problems found (none: an empty list).
	async stop() {
		const problems = [];
		if (this.proc.exitCode !== null || this.proc.signalCode !== null) {
			problems.push(`relightd had already exited (${this.proc.exitCode ?? this.proc.signalCode})`);
		} else {
			this.proc.kill('SIGTERM');
			const r = await Promise.race([this.exited, sleep(30000).then(() => null)]);
			if (!r) {
				problems.push('relightd did not exit within 30 s of SIGTERM');
				this.proc.kill('SIGKILL');
				await this.exited;
			} else if (r.code !== 0) {
				problems.push(`relightd exited with ${r.code ?? r.signal} after SIGTERM`);
			}
		}
		const bad = this.stderr().split('\n').filter((l) =>
			/AddressSanitizer|LeakSanitizer|runtime error/.test(l));
		if (bad.length)
			problems.push(`sanitizer report: ${bad.slice(0, 3).join(' | ')}`);
		return problems;
	}
}

function sleep(ms) {
	return new Promise((resolve) => setTimeout(resolve, ms));
}

// ---------------------------------------------------------------------------
// The page
// ---------------------------------------------------------------------------

async function state(page) {
	return page.evaluate(() => window.relightViewer ? window.relightViewer.state : null);
}

// Waits until pred(state) holds; throws with the last state when it does not.
async function until(page, what, pred, timeout = 20000) {
	const deadline = Date.now() + timeout;
	let s = null;
	while (Date.now() < deadline) {
		s = await state(page);
		if (s && pred(s))
			return s;
		await sleep(25);
	}
	throw new Error(`timed out after ${timeout / 1000} s waiting for ${what}; state ${JSON.stringify(s)}`);
}

// The canvas's pixels (RGBA, rows top first).
async function canvasPixels(page) {
	const b64 = await page.evaluate(() => {
		const c = document.getElementById('image');
		const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
		let s = '';
		for (let i = 0; i < d.length; i += 0x8000)
			s += String.fromCharCode.apply(null, d.subarray(i, i + 0x8000));
		return btoa(s);
	});
	return Buffer.from(b64, 'base64');
}

// How two RGBA images differ over the channels listed.
function compare(a, b, chans = [0, 1, 2, 3]) {
	let differ = 0;
	let worst = 0;
	let at = -1;
	if (a.length !== b.length)
		return {differ: Infinity, worst: 256, at: -1};
	for (let i = 0; i < a.length; i += 4) {
		let d = 0;
		for (const c of chans)
			d = Math.max(d, Math.abs(a[i + c] - b[i + c]));
		if (d) {
			differ++;
			if (d > worst) {
				worst = d;
				at = i / 4;
			}
		}
	}
	return {differ, worst, at};
}

function describe(c, width) {
	return `${c.differ} pixels differ, the most by ${c.worst}` +
		(c.at >= 0 ? ` at (${c.at % width}, ${Math.floor(c.at / width)})` : '');
}

async function screenshot(page, name) {
	const file = path.join(ARTIFACTS, name);
	await page.screenshot({path: file});
	console.log(`${NAME}: screenshot ${file}`);
	return file;
}


// Edit requests a page sent, from its WebSocket frames.
const EDIT_OPS = new Set(['set', 'add_light', 'remove_light', 'solo', 'mute', 'freeze']);

// The text frames a page sends, and the most "set" requests it ever had
// unanswered at once (sent.maxSetsInFlight), from its WebSocket frames.
function watchFrames(page) {
	const sent = [];
	sent.maxSetsInFlight = 0;
	page.on('websocket', (ws) => {
		const open = new Set();
		ws.on('framesent', (f) => {
			if (typeof f.payload !== 'string')
				return;
			let m;
			try {
				m = JSON.parse(f.payload);
			} catch (e) {
				m = {op: '?', text: f.payload};
			}
			sent.push(m);
			if (m.op === 'set') {
				open.add(m.id);
				sent.maxSetsInFlight = Math.max(sent.maxSetsInFlight, open.size);
			}
		});
		ws.on('framereceived', (f) => {
			if (typeof f.payload !== 'string')
				return;
			try {
				open.delete(JSON.parse(f.payload).id);
			} catch (e) {
				// not JSON: the page reports it
			}
		});
	});
	return sent;
}

function watchErrors(page, base) {
	const errors = [];
	const foreign = [];
	page.on('pageerror', (e) => errors.push(`uncaught: ${e.message}`));
	page.on('console', (m) => {
		// A refused WebSocket is logged by the browser itself while the
		// daemon is down; that is expected here.
		if (m.type() === 'error' && !/WebSocket connection|ERR_CONNECTION_REFUSED/.test(m.text()))
			errors.push(`console: ${m.text()}`);
	});
	page.on('request', (r) => {
		const u = r.url();
		if (!u.startsWith(base) && !u.startsWith('data:') && !u.startsWith('blob:'))
			foreign.push(u);
	});
	return {errors, foreign};
}

// ---------------------------------------------------------------------------
// The test
// ---------------------------------------------------------------------------

function findChromium() {
	const names = process.env.RELIGHT_CHROMIUM ? [process.env.RELIGHT_CHROMIUM] :
		['chromium', 'chromium-browser', 'google-chrome-stable', 'google-chrome'];
	for (const n of names) {
		if (n.includes('/')) {
			if (fs.existsSync(n))
				return n;
			continue;
		}
		for (const dir of (process.env.PATH || '/usr/bin').split(':')) {
			const p = path.join(dir, n);
			try {
				fs.accessSync(p, fs.constants.X_OK);
				return p;
			} catch (e) {
				// not here
			}
		}
	}
	return null;
}

function bakeShots(relight) {
	// The integration tests' folder of baked examples, baked under their lock.
	const py = 'import sys; sys.path.insert(0, sys.argv[1]); import harness; print(harness.bake_shots(sys.argv[2]))';
	const r = run('python3', ['-c', py, path.join(SOURCE_DIR, 'tests', 'integration'), relight],
		      {env: Object.assign({}, process.env, {RELIGHT_BUILD_DIR: BUILD_DIR}), timeout: 600000});
	if (r.status !== 0)
		throw new Error(`cannot bake the example shots: ${r.stderr.slice(0, 2000)}${r.error || ''}`);
	return r.stdout.trim().split('\n').pop();
}

async function main() {
	if (process.argv.length < 4) {
		console.error('usage: node test_viewer.mjs PATH/TO/relightd PATH/TO/relight');
		process.exit(2);
	}
	const relightd = path.resolve(process.argv[2]);
	const relight = path.resolve(process.argv[3]);
	const major = Number(process.versions.node.split('.')[0]);
	if (major < 18)
		skip(`node ${process.versions.node} is too old (18 or newer)`);
	let chromium;
	try {
		({chromium} = createRequire(path.join(HERE, 'package.json'))('playwright-core'));
	} catch (e) {
		skip(`playwright-core is not installed in ${HERE}/node_modules (scripts/setup installs it; ` +
		     `or run 'npm ci' there): ${e.message.split('\n')[0]}`);
	}
	const browserPath = findChromium();
	if (!browserPath)
		skip('no Chromium (apt-get install chromium, or set RELIGHT_CHROMIUM)');

	fs.mkdirSync(ARTIFACTS, {recursive: true});
	const tmp = fs.mkdtempSync(path.join(BUILD_DIR, 'web-tmp-'));
	const shots = bakeShots(relight);
	const snapshots = path.join(tmp, 'snapshots');
	fs.mkdirSync(snapshots);
	const tokenFile = path.join(tmp, 'tokens');
	fs.writeFileSync(tokenFile, 'tok-editor-1 editor\ntok-viewer-1 viewer\n');
	const viewerDir = path.join(SOURCE_DIR, 'clients', 'web');
	const daemonOpts = {tmp, shots, snapshots, viewer: viewerDir, tokenFile};
	let daemon = new Daemon(relightd, daemonOpts);
	await daemon.start();
	note(`relightd at ${daemon.base}, shots in ${shots}`);

	let browser;
	try {
		browser = await chromium.launch({executablePath: browserPath, headless: true});
	} catch (e) {
		await daemon.stop();
		skip(`Chromium at ${browserPath} does not start: ${e.message.split('\n')[0]}`);
	}
	const context = await browser.newContext({acceptDownloads: true, viewport: {width: 1280, height: 720}});
	const remote = (args, ...cmds) => run(relight, ['remote', '-q', '--token', 'tok-editor-1', ...args,
							daemon.ws, ...cmds]);
	const page = await context.newPage();
	const sent = watchFrames(page);
	const watch = watchErrors(page, daemon.base);
	let width = 0;
	let height = 0;
	let edited = null;            // the canvas after the edit
	let reference = null;         // the daemon's PNG of that state

	await section('load', async () => {
		await page.goto(`${daemon.base}/?token=tok-editor-1&shot=shadows`);
		const s = await until(page, 'the final level', (s) => s.final);
		width = s.width;
		height = s.height;
		check(s.role === 'editor' && s.shot === 'shadows' && width === 640 && height === 360,
		      'opened shadows 640x360 as an editor', JSON.stringify(s));
		check(!page.url().includes('token'), 'the token is taken out of the address bar', page.url());
		const names = await page.$$eval('#light-list section.light', (els) => els.map((e) => e.dataset.light));
		check(JSON.stringify(names) === '["1","2","3"]', 'a card for each of the lights 1, 2, 3', JSON.stringify(names));
		const cone = await page.$eval('section.light[data-light="2"] input[type=range][data-param="coneangle"]',
					      (e) => [Number(e.min), Number(e.max)]);
		check(cone[0] === 0 && Math.abs(cone[1] - Math.PI) < 1e-6, "the cone angle's slider spans [0, pi]",
		      JSON.stringify(cone));
		const inten = await page.$eval('section.light[data-light="2"] input[type=range][data-param="intensity"]',
					       (e) => [Number(e.min), Number(e.max), Number(e.value)]);
		check(inten[0] === 0 && inten[1] === 240 && Math.abs(inten[2] - 60) < 0.5,
		      "the intensity's slider spans 0 to 4 times its value (60)", JSON.stringify(inten));
		const colour = await page.$$eval('section.light[data-light="3"] .param-color input',
						 (els) => els.map((e) => e.type + ':' + e.value));
		check(colour.length === 4 && colour[0].startsWith('color:#') && colour[3] === 'number:0.8',
		      "a colour is a picker and three numeric fields (light 3's lightcolor)", JSON.stringify(colour));
		const from = await page.$$eval('section.light[data-light="2"] .param-point input', (els) => els.length);
		check(from === 6, 'a point is three numeric fields (from, to)', `${from} fields`);
		check(await page.$eval('#role-badge', (e) => e.hidden), 'no "view only" badge for an editor');
		check(sent.filter((m) => EDIT_OPS.has(m.op)).length === 0, 'no edit sent on load');
		await screenshot(page, '01-loaded.png');
	});

	await section('edit', async () => {
		const before = await canvasPixels(page);
		const e0 = (await state(page)).edit;
		const slider = page.locator('section.light[data-light="2"] input[type=range][data-param="intensity"]');
		const box = await slider.boundingBox();
		const y = box.y + box.height / 2;
		// From the thumb (a quarter of the way: 60 of 240) to 70 %, as a user drags.
		await page.mouse.move(box.x + box.width * 0.25, y);
		await page.mouse.down();
		await page.mouse.move(box.x + box.width * 0.7, y, {steps: 20});
		await page.mouse.up();
		const s = await until(page, "the edit's final level",
			(s) => s.pendingEdits === 0 && s.ackedEdit > e0 && s.edit === s.ackedEdit && s.final);
		const sets = sent.filter((m) => m.op === 'set');
		check(sets.length >= 1 && sets.length <= 21, 'the drag sent between 1 and 21 sets',
		      `${sets.length} sets`);
		check(sent.maxSetsInFlight === 1, 'never more than one set in flight',
		      `${sent.maxSetsInFlight} at once`);
		const value = await slider.evaluate((e) => Number(e.value));
		const field = await page.$eval('section.light[data-light="2"] input[type=number][data-param="intensity"]',
					       (e) => Number(e.value));
		const last = sets.length ? sets[sets.length - 1].params.intensity : NaN;
		check(value > 120 && Math.abs(last - value) < 1e-9,
		      'the last set carries the slider\'s final value', `slider ${value}, last set ${last}`);
		check(Math.abs(field - value) < 1e-3 * value, 'the numeric field follows the slider', `${field} vs ${value}`);
		check(s.latency && s.latency.edit === s.edit && s.latency.firstTileMs > 0 &&
		      s.latency.finalMs >= s.latency.firstTileMs,
		      'the latency of the newest edit is measured (first tile, final level)', JSON.stringify(s.latency));
		const status = await page.textContent('#status-main');
		check(/first tile [0-9.]+ ms/.test(status) && /final [0-9.]+ ms/.test(status) &&
		      status.includes(`edit ${s.edit}`) && status.includes('level 3/3 final'),
		      'the status line shows the edit, the level and the latency', status);
		note(`${sets.length} sets for the drag; edit ${s.edit}: first tile ${s.latency.firstTileMs.toFixed(1)} ms, ` +
		     `final ${s.latency.finalMs.toFixed(1)} ms`);
		edited = await canvasPixels(page);
		const changed = compare(before, edited, [0, 1, 2]);
		check(changed.differ > 5000, 'the image changed with the intensity', describe(changed, width));
		const png = path.join(tmp, 'daemon.png');
		const r = remote([], 'open', 'shadows', 'wait', 'snapshot', png);
		if (!check(r.status === 0, 'relight remote writes the PNG of the state', r.stderr.slice(0, 500)))
			return;
		reference = decodePng(fs.readFileSync(png));
		check(reference.width === width && reference.height === height && reference.channels === 4,
		      "the daemon's PNG is RGBA of the shot's size");
		const c = compare(edited, reference.pixels, [0, 1, 2]);
		check(c.differ === 0, "the canvas equals the daemon's snapshot exactly (RGB)", describe(c, width));
		const opaque = edited.every((v, i) => i % 4 !== 3 || v === 255);
		check(opaque, 'the canvas shows the image over black (alpha 255)');
		await screenshot(page, '02-edited.png');
	});

	await section('display', async () => {
		if (!reference)
			return;
		await page.fill('#exposure-num', '1');
		await until(page, 'exposure +1', (s) => s.stops === 1);
		await page.evaluate(() => new Promise((r) => requestAnimationFrame(r)));
		const bright = await canvasPixels(page);
		const want = Buffer.alloc(bright.length);
		for (let i = 0; i < want.length; i++)
			want[i] = i % 4 === 3 ? 255 : displayed(reference.pixels[i], 1, 2.2);
		const c = compare(bright, want);
		check(c.differ === 0, 'at +1 stop the canvas is the documented transform of the pixels',
		      describe(c, width));
		const brighter = compare(bright, reference.pixels, [0, 1, 2]);
		check(brighter.differ > 10000, '+1 stop changes the canvas', describe(brighter, width));
		await screenshot(page, '03-exposure.png');
		await page.fill('#gamma-num', '1.8');
		await until(page, 'gamma 1.8', (s) => s.gamma === 1.8);
		const g = await canvasPixels(page);
		for (let i = 0; i < want.length; i++)
			want[i] = i % 4 === 3 ? 255 : displayed(reference.pixels[i], 1, 1.8);
		check(compare(g, want).differ === 0, 'gamma 1.8 at +1 stop is the documented transform',
		      describe(compare(g, want), width));
		await page.click('#display-reset');
		await until(page, 'the display reset', (s) => s.stops === 0 && s.gamma === 2.2);
		const back = compare(await canvasPixels(page), reference.pixels, [0, 1, 2]);
		check(back.differ === 0, 'reset: the canvas is the daemon\'s pixels again', describe(back, width));
	});

	await section('png', async () => {
		if (!reference)
			return;
		const [dl] = await Promise.all([page.waitForEvent('download'), page.click('#save-png')]);
		const file = path.join(ARTIFACTS, 'viewer.png');
		await dl.saveAs(file);
		check(/^shadows-e\d+\.png$/.test(dl.suggestedFilename()), 'the PNG is named after the shot and edit',
		      dl.suggestedFilename());
		const p = decodePng(fs.readFileSync(file));
		const c = compare(p.pixels, reference.pixels);
		check(p.width === width && p.height === height && p.channels === 4 && c.differ === 0,
		      "the downloaded PNG equals the daemon's, alpha included", describe(c, width));
		const partial = reference.pixels.filter((v, i) => i % 4 === 3 && v > 0 && v < 255).length;
		note(`PNG: ${partial} pixels of partial alpha kept exactly; ${file}`);
	});

	await section('exr', async () => {
		const [dl] = await Promise.all([page.waitForEvent('download', {timeout: 60000}), page.click('#save-exr')]);
		const file = path.join(ARTIFACTS, 'viewer.exr');
		await dl.saveAs(file);
		const buf = fs.readFileSync(file);
		let exr;
		try {
			exr = parseExr(buf);
		} catch (e) {
			check(false, 'the EXR parses', e.message);
			return;
		}
		check(true, 'the EXR parses: magic, version, header, offsets, scanlines');
		check(exr.channels.map((c) => c.name).join('') === 'ABGR' &&
		      exr.channels.every((c) => c.type === 1 && c.xs === 1 && c.ys === 1),
		      'channels A, B, G, R, all HALF, sampling 1', JSON.stringify(exr.channels));
		check(JSON.stringify(exr.dataWindow) === JSON.stringify([0, 0, width - 1, height - 1]) &&
		      JSON.stringify(exr.displayWindow) === JSON.stringify(exr.dataWindow),
		      'data and display windows are the image', JSON.stringify(exr.dataWindow));
		check(exr.attrs.pixelAspectRatio.data.readFloatLE(0) === 1 &&
		      exr.attrs.screenWindowWidth.data.readFloatLE(0) === 1, 'pixel aspect ratio and screen window width 1');
		const theirs = path.join(tmp, 'daemon.exr');
		const r = remote(['--format', 'rgba16f'], 'open', 'shadows', 'wait', 'snapshot', theirs);
		if (!check(r.status === 0, 'relight remote writes the rgba16f EXR of the state', r.stderr.slice(0, 500)))
			return;
		const d = run(relight, ['diff', '--json', file, theirs]);
		let j = null;
		try {
			j = JSON.parse(d.stdout);
		} catch (e) {
			// reported below
		}
		check(d.status === 0 && j && j.rmse === 0 && j.max_pct === 0 && j.max_rel === 0 &&
		      j.alpha && j.alpha.rmse === 0 && j.width === width && j.height === height,
		      "OpenEXR reads the viewer's EXR as identical to the daemon's rgba16f snapshot (relight diff)",
		      `status ${d.status}: ${d.stdout.slice(0, 400)} ${d.stderr.slice(0, 400)}`);
		const h = run('exrheader', [file]);
		if (h.error)
			note('no exrheader here: its check is left out');
		else
			check(h.status === 0 && /compression.*none/i.test(h.stdout), 'exrheader reads it: no compression',
			      (h.stdout + h.stderr).slice(0, 400));
		if (!reference)
			return;
		// Within one 8-bit step of the PNG: the 8-bit values are rounded
		// from the floats the halves are rounded from.
		let worst = 0;
		let over = 0;
		const names = ['R', 'G', 'B'];
		for (let p = 0; p < width * height; p++) {
			for (let c = 0; c < 4; c++) {
				const v = halfToFloat(exr.planes[c < 3 ? names[c] : 'A'][p]);
				const b = c < 3 ? srgb8(v) : Math.floor(255 * Math.min(1, Math.max(0, v)) + 0.5);
				const dd = Math.abs(b - reference.pixels[4 * p + c]);
				worst = Math.max(worst, dd);
				if (dd > 1)
					over++;
			}
		}
		check(over === 0, 'the EXR is within one 8-bit step of the PNG everywhere',
		      `${over} values differ by more, the most by ${worst}`);
		note(`EXR: ${buf.length} bytes, largest 8-bit difference from the PNG ${worst}; ${file}`);
	});

	await section('pick', async () => {
		const box = await page.locator('#image').boundingBox();
		const px = Math.floor(width * 0.4);
		const py = Math.floor(height * 0.55);
		await page.mouse.click(box.x + (px + 0.5) * box.width / width, box.y + (py + 0.5) * box.height / height);
		const s = await until(page, 'a pick answer or note', (s) => s.pick || s.pickNote, 10000);
		const picks = sent.filter((m) => m.op === 'pick');
		check(picks.length === 1 && picks[0].x === px && picks[0].y === py && Number.isInteger(picks[0].id),
		      'a click sends {"op":"pick","id","x","y"} of the pixel under it', JSON.stringify(picks));
		const info = await page.textContent('#pick-info');
		if (s.pickNote) {
			check(info.includes('picking needs a newer relightd') && s.pickNote === 'picking needs a newer relightd',
			      'an older daemon: the note says picking needs a newer relightd', info);
			note('this relightd does not know "pick" yet: the note was shown');
		} else {
			check(s.pick.x === px && s.pick.y === py && Array.isArray(s.pick.lights),
			      'the picked reply is for that pixel', JSON.stringify(s.pick));
			check(info.startsWith(`${px}, ${py}:`), 'the pick is shown', info);
			note(`picked (${px}, ${py}): ${info}`);
		}
		await screenshot(page, '04-pick.png');
	});

	await section('lights', async () => {
		const light = (n, rest) => `section.light[data-light="${n}"] ${rest}`;
		// An edit by a click, waited for to its final level.
		const edit = async (what, selector) => {
			const e0 = (await state(page)).ackedEdit;
			await page.click(selector);
			return until(page, what, (s) => s.ackedEdit > e0 && s.edit === s.ackedEdit && s.final &&
				s.pendingEdits === 0);
		};
		const base = await canvasPixels(page);
		await edit('mute 3', light(3, 'button.mute'));
		check(await page.getAttribute(light(3, 'button.mute'), 'aria-pressed') === 'true', 'mute is pressed');
		const muted = await canvasPixels(page);
		check(compare(base, muted, [0, 1, 2]).differ > 1000, 'muting light 3 changes the image');
		await edit('unmute 3', light(3, 'button.mute'));
		let c = compare(base, await canvasPixels(page));
		check(c.differ === 0, 'unmuted: the image as before', describe(c, width));
		await edit('solo 2', light(2, 'button.solo'));
		check(await page.getAttribute(light(2, 'button.solo'), 'aria-pressed') === 'true' &&
		      await page.$eval(light(1, ''), (e) => e.closest('section').classList.contains('muted')),
		      'solo is pressed on 2, light 1 is dimmed');
		check(compare(base, await canvasPixels(page), [0, 1, 2]).differ > 1000, 'solo changes the image');
		await edit('solo off', light(2, 'button.solo'));
		c = compare(base, await canvasPixels(page));
		check(c.differ === 0, 'solo off: the image as before', describe(c, width));
		await page.fill('#add-light-shader', 'pointlight');
		await page.fill('#add-light-name', 'L4');
		await edit('add L4', '#add-light button[type=submit]');
		await page.waitForSelector(light('L4', 'input[type=range][data-param="intensity"]'), {timeout: 10000});
		const adds = sent.filter((m) => m.op === 'add_light');
		check(adds.length === 1 && adds[0].light === 'L4' && adds[0].shader === 'pointlight',
		      'add_light is sent with the shader and name', JSON.stringify(adds));
		await page.click(light('L4', 'button.remove'));
		check(await page.isVisible(light('L4', 'input')), 'one click on remove only arms it');
		await edit('remove L4', light('L4', 'button.remove'));
		await page.waitForSelector(light('L4', ''), {state: 'detached', timeout: 10000});
		await until(page, 'the final level after the removal', (s) => s.final);
		c = compare(base, await canvasPixels(page));
		check(c.differ === 0, 'L4 removed: the image as before', describe(c, width));
		// Freezing is last: a light taken out of the light cache (float64) adds its
		// contribution to the rounded sum in float32, so the same lights, frozen or
		// not, may differ in the last bit (docs/runtime.md, "Light cache"); the
		// comparisons with the first image above all end with every light frozen.
		const f0 = await state(page);
		await page.click(light(1, 'button.freeze'));
		await until(page, 'freeze 1', (s) => s.ackedEdit >= f0.ackedEdit && s.pendingEdits === 0);
		await page.waitForSelector(`${light(1, 'button.freeze')}[aria-pressed=true]`, {timeout: 5000});
		await page.click(light(1, 'button.freeze'));
		await page.waitForSelector(`${light(1, 'button.freeze')}[aria-pressed=false]`, {timeout: 5000});
		const freezes = sent.filter((m) => m.op === 'freeze');
		check(freezes.length === 2 && freezes[0].freeze === true && freezes[1].freeze === false &&
		      freezes[0].light === '1', 'freeze and unfreeze are sent', JSON.stringify(freezes));
		check((await state(page)).edit === f0.edit, 'a freeze changes no pixel: no new edit shown');
	});

	await section('stale tiles', async () => {
		// A page whose WebSocket goes through the test, which adds tiles of
		// its own to what the daemon sends.
		const tpage = await context.newPage();
		let toPage = null;
		await tpage.routeWebSocket(/\/ws$/, (ws) => {
			ws.connectToServer();
			toPage = ws;
		});
		await tpage.goto(`${daemon.base}/?token=tok-editor-1&shot=shadows`);
		let s = await until(tpage, 'the final level (routed)', (s) => s.final);
		const tile = (edit, magic = 'RLT1') => {
			const b = Buffer.alloc(36 + 64 * 64 * 4, 0xff);
			b.write(magic, 0, 'latin1');
			[36, edit, 3, 1, 0, 0, 64, 64].forEach((v, i) => b.writeUInt32LE(v, 4 + 4 * i));
			return b;
		};
		const before = await canvasPixels(tpage);
		const dropped = s.tilesDropped;
		check(s.edit > 0, 'the shot has edits', `edit ${s.edit}`);
		toPage.send(tile(s.edit - 1));
		s = await until(tpage, 'the stale tile dropped', (v) => v.tilesDropped > dropped, 5000);
		let c = compare(before, await canvasPixels(tpage));
		check(c.differ === 0, 'a tile of an older edit is not drawn', describe(c, width));
		toPage.send(tile(s.edit, 'RLTX'));
		s = await until(tpage, 'the bad tile refused', (v) => v.badTiles === 1, 5000);
		c = compare(before, await canvasPixels(tpage));
		check(c.differ === 0, 'a frame with a bad magic is refused', describe(c, width));
		toPage.send(tile(s.edit));
		await until(tpage, 'the current tile drawn', (v) => v.tilesDrawn > s.tilesDrawn, 5000);
		c = compare(before, await canvasPixels(tpage));
		check(c.differ > 0 && c.differ <= 64 * 64, 'a tile of the current edit is drawn, where it says',
		      describe(c, width));
		await tpage.close();
	});

	await section('viewer token', async () => {
		const vpage = await context.newPage();
		const vsent = watchFrames(vpage);
		const vwatch = watchErrors(vpage, daemon.base);
		await vpage.goto(`${daemon.base}/?token=tok-viewer-1&shot=shadows`);
		let s = await until(vpage, 'the final level (viewer)', (s) => s.final);
		check(s.role === 'viewer', 'hello says viewer', s.role);
		check(await vpage.isVisible('#role-badge') && (await vpage.textContent('#role-badge')).includes('view only'),
		      'the "view only" badge shows');
		const controls = await vpage.$$eval('#light-list input, #light-list button.tog',
			(els) => els.map((e) => e.disabled || Boolean(e.closest('fieldset:disabled'))));
		check(controls.length > 20 && controls.every(Boolean), 'every light control is disabled',
		      `${controls.filter((d) => !d).length} of ${controls.length} enabled`);
		check(!(await vpage.isVisible('#add-light')), 'no add-light form');
		// Try anyway: a drag over the slider, clicks on solo and mute, keys.
		const slider = vpage.locator('section.light[data-light="2"] input[type=range][data-param="intensity"]');
		const box = await slider.boundingBox();
		await vpage.mouse.move(box.x + 2, box.y + box.height / 2);
		await vpage.mouse.down();
		await vpage.mouse.move(box.x + box.width - 2, box.y + box.height / 2, {steps: 5});
		await vpage.mouse.up();
		await vpage.click('section.light[data-light="1"] button.solo', {force: true, timeout: 2000}).catch(() => {});
		await vpage.click('section.light[data-light="3"] button.mute', {force: true, timeout: 2000}).catch(() => {});
		await vpage.keyboard.press('ArrowRight');
		await sleep(400);
		s = await state(vpage);
		const edits = vsent.filter((m) => EDIT_OPS.has(m.op));
		check(edits.length === 0 && s.editsSent === 0, 'no edit sent by a viewer', JSON.stringify(edits));
		await screenshot(vpage, '05-viewer.png');
		// The editor edits: the viewer sees it.
		const e0 = (await state(page)).edit;
		await page.fill('section.light[data-light="3"] input[type=number][data-param="intensity"]', '12');
		const es = await until(page, "the editor's second edit", (s) => s.ackedEdit > e0 && s.final &&
			s.pendingEdits === 0 && s.edit === s.ackedEdit);
		s = await until(vpage, "the editor's edit at the viewer", (v) => v.edit === es.edit && v.final);
		const a = await canvasPixels(page);
		const b = await canvasPixels(vpage);
		const c = compare(a, b);
		check(c.differ === 0, "the viewer shows the editor's edit, the same pixels", describe(c, width));
		check(vwatch.errors.length === 0, 'no errors on the viewer\'s page', vwatch.errors.join(' | '));
		await vpage.close();
	});

	await section('dialog and keyboard', async () => {
		const dpage = await context.newPage();
		const dsent = watchFrames(dpage);
		await dpage.goto(`${daemon.base}/?token=tok-editor-1`);
		await dpage.waitForSelector('#connect-dialog[open]', {timeout: 10000});
		await dpage.waitForFunction(() => document.querySelectorAll('#shot-list option').length >= 2);
		const offered = await dpage.$$eval('#shot-list option', (els) => els.map((e) => e.value));
		check(offered.includes('shadows') && offered.includes('lights32'), 'the dialog offers the shots',
		      JSON.stringify(offered));
		await dpage.fill('#connect-shot', 'lights32');
		await dpage.press('#connect-shot', 'Enter');
		let s = await until(dpage, 'lights32 at its final level', (s) => s.shot === 'lights32' && s.final);
		check(dpage.url().endsWith('/?shot=lights32'), 'the shot is put in the address', dpage.url());
		const cards = await dpage.$$eval('#light-list section.light', (els) => els.length);
		check(cards >= 32, 'lights32 lists its lights', `${cards} cards`);
		// Keyboard alone: Tab reaches the first slider, an arrow key edits.
		const first = dpage.locator('#light-list input[type=range]').first();
		const param = await first.getAttribute('data-param');
		const v0 = Number(await first.inputValue());
		await first.focus();
		await dpage.keyboard.press('ArrowRight');
		s = await until(dpage, 'the keyboard edit', (s) => s.ackedEdit >= 1 && s.pendingEdits === 0 && s.final);
		const sets = dsent.filter((m) => m.op === 'set');
		check(sets.length === 1 && sets[0].params[param] > v0, 'an arrow key on a slider sends one edit',
		      JSON.stringify(sets));
		const focusable = await dpage.evaluate(() => {
			const b = document.querySelector('#light-list button.mute');
			b.focus();
			return document.activeElement === b;
		});
		check(focusable, 'the light toggles take the focus');
		await dpage.keyboard.press('Enter');
		await dpage.waitForSelector('#light-list button.mute[aria-pressed=true]', {timeout: 10000});
		await dpage.keyboard.press('Space');
		await dpage.waitForSelector('#light-list button.mute[aria-pressed=true]', {state: 'detached', timeout: 10000});
		check(dsent.filter((m) => m.op === 'mute').length === 2, 'Enter and Space press a toggle');
		await screenshot(dpage, '06-lights32.png');
		await dpage.close();
	});

	await section('bad token', async () => {
		const bpage = await context.newPage();
		await bpage.goto(`${daemon.base}/?token=tok-wrong-0&shot=shadows`);
		const s = await until(bpage, 'the auth banner', (s) => s.banner && s.phase === 'auth', 10000);
		const text = await bpage.textContent('#banner-text');
		check(s.banner.kind === 'error' && text.includes('auth'), 'an error banner names the auth error', text);
		check(await bpage.isVisible('#connect-dialog'), 'the dialog asks for a token');
		await screenshot(bpage, '07-auth.png');
		await bpage.close();
	});

	await section('reconnect', async () => {
		const port = daemon.port;
		const problems = await daemon.stop();
		check(problems.length === 0, 'relightd stops cleanly on SIGTERM', problems.join('; '));
		let s = await until(page, 'the reconnect banner', (s) => s.banner && s.phase === 'disconnected', 10000);
		const text = await page.textContent('#banner-text');
		check(s.banner.kind === 'warn' && /reconnecting/.test(text), 'a banner says the page is reconnecting', text);
		await screenshot(page, '08-reconnecting.png');
		await sleep(1200);
		daemon = new Daemon(relightd, daemonOpts);
		await daemon.start(port, 20);
		const t = Date.now();
		s = await until(page, 'the page back on the new daemon', (s) => s.phase === 'open' && s.final &&
			!s.banner && s.reconnects >= 1, 20000);
		note(`reconnected ${((Date.now() - t) / 1000).toFixed(1)} s after the daemon was back; ` +
		     `${s.reconnects} reconnect(s)`);
		check(s.shot === 'shadows' && s.final, 'reconnected by itself, the shot open again at its final level');
		await screenshot(page, '09-reconnected.png');
	});

	check(watch.errors.length === 0, 'no errors on the page', watch.errors.join(' | '));
	check(watch.foreign.length === 0, 'nothing fetched from elsewhere', watch.foreign.join(' '));
	await browser.close();
	checks.section = 'end';
	const problems = await daemon.stop();
	check(problems.length === 0, 'relightd stops cleanly on SIGTERM', problems.join('; '));
	if (checks.failed)
		console.error(`${NAME}: relightd's stderr: ${daemon.stderrPath}; files in ${tmp}`);
	else
		fs.rmSync(tmp, {recursive: true, force: true});
	console.log(`${NAME}: ${checks.n} checks, ${checks.failed} failed, ${((Date.now() - T0) / 1000).toFixed(1)} s`);
	process.exit(checks.failed ? 1 : 0);
}

main().catch((e) => {
	console.error(`${NAME}: ${e && e.stack ? e.stack : e}`);
	process.exit(1);
});
