// The light list: a card per light of the "opened" reply, with a control
// for each parameter generated from its metadata (type, value, min, max),
// and the solo, mute, freeze and remove buttons.

import {linearToSrgb, srgbToLinear} from './image.js';

// Bounds past this are the daemon's way of saying "unbounded" (it sends
// about +-1e18 for parameters the shader does not limit).
const UNBOUNDED = 1e15;

let uid = 0;

function el(tag, props = {}, ...children) {
	const e = document.createElement(tag);
	for (const [k, v] of Object.entries(props)) {
		if (k === 'class')
			e.className = v;
		else if (k === 'text')
			e.textContent = v;
		else if (k.startsWith('aria-') || k.startsWith('data-') || k === 'role' || k === 'for')
			e.setAttribute(k, v);
		else
			e[k] = v;
	}
	for (const c of children)
		if (c !== null && c !== undefined)
			e.append(c);
	return e;
}

// A number as a field shows it: at most 6 significant digits, no float noise.
export function formatNumber(v) {
	if (!Number.isFinite(v))
		return String(v);
	if (Number.isInteger(v))
		return String(v);
	return String(Number(v.toPrecision(6)));
}

function bounded(p) {
	return Math.abs(p.min) < UNBOUNDED && Math.abs(p.max) < UNBOUNDED && p.max > p.min;
}

// The slider's range for a float: its bounds when the shader gives real
// ones (a cone angle's [0, pi]); otherwise 0 to 4 times the value (or the
// value's negative counterpart), so that a drag covers the useful part of
// an unbounded intensity. The numeric field still takes any value in
// [min, max], and the slider's range follows a value typed outside it.
export function sliderRange(p, v) {
	if (bounded(p))
		return [p.min, p.max];
	let lo, hi;
	if (v > 0) {
		lo = 0;
		hi = 4 * v;
	} else if (v < 0) {
		lo = 4 * v;
		hi = 0;
	} else {
		lo = 0;
		hi = 1;
	}
	return [Math.max(lo, p.min), Math.min(hi, p.max)];
}

function hex2(v) {
	return Math.round(255 * linearToSrgb(v)).toString(16).padStart(2, '0');
}

// The colour picker shows a linear colour as sRGB, clamped to [0, 1].
function colourToHex(c) {
	return '#' + hex2(c[0]) + hex2(c[1]) + hex2(c[2]);
}

function hexToColour(h) {
	const n = parseInt(h.slice(1), 16);
	return [(n >> 16) & 255, (n >> 8) & 255, n & 255].map((b) => srgbToLinear(b / 255));
}

// One parameter's control. `send(value)` is called with the whole value (a
// number, or an array for colours, points and matrices) as the user moves it.
class ParamControl {
	constructor(light, p, send) {
		this.light = light;
		this.p = p;
		this.send = send;
		this.value = Array.isArray(p.value) ? p.value.slice() : p.value;
		this.fields = [];
		this.slider = null;
		this.picker = null;
		this.row = this.build();
	}

	label(forId) {
		return el('label', {class: 'pname', for: forId, text: this.p.name,
				    title: `${this.p.name} (${this.p.type})`});
	}

	numberField(i, labelText) {
		const id = `p${++uid}`;
		const f = el('input', {type: 'number', id, step: 'any', class: 'num',
				       'aria-label': `${this.light} ${this.p.name}${labelText ? ' ' + labelText : ''}`});
		if (Math.abs(this.p.min) < UNBOUNDED)
			f.min = String(this.p.min);
		if (Math.abs(this.p.max) < UNBOUNDED)
			f.max = String(this.p.max);
		f.dataset.param = this.p.name;
		f.addEventListener('input', () => this.typed(i, f));
		f.addEventListener('change', () => this.typed(i, f, true));
		this.fields.push(f);
		return f;
	}

	// A value typed into field i; sent when it is a number within the bounds.
	typed(i, f, final = false) {
		const v = f.valueAsNumber;
		const ok = Number.isFinite(v) && v >= this.p.min && v <= this.p.max;
		f.setAttribute('aria-invalid', ok ? 'false' : 'true');
		f.title = ok ? '' : `a number from ${formatNumber(this.p.min)} to ${formatNumber(this.p.max)}`;
		if (!ok) {
			if (final && f.value === '')
				this.show();
			return;
		}
		if (Array.isArray(this.value)) {
			if (this.value[i] === v)
				return;
			this.value[i] = v;
		} else {
			if (this.value === v)
				return;
			this.value = v;
		}
		this.show(f);
		this.send(Array.isArray(this.value) ? this.value.slice() : this.value);
	}

	build() {
		const p = this.p;
		const row = el('div', {class: `param param-${p.type}`});
		if (p.type === 'float' && !Array.isArray(p.value)) {
			const f = this.numberField(0, '');
			const [lo, hi] = sliderRange(p, p.value);
			const s = el('input', {type: 'range', class: 'slider', min: String(lo), max: String(hi),
					      step: String((hi - lo) / 1000),
					      'aria-label': `${this.light} ${p.name}`});
			s.dataset.param = p.name;
			s.addEventListener('input', () => {
				const v = s.valueAsNumber;
				if (!Number.isFinite(v) || v === this.value)
					return;
				this.value = v;
				this.show(s);
				this.send(v);
			});
			this.slider = s;
			row.append(this.label(f.id), s, f);
		} else if (p.type === 'color' && Array.isArray(p.value) && p.value.length === 3) {
			const id = `p${++uid}`;
			const picker = el('input', {type: 'color', id, class: 'swatch',
						   'aria-label': `${this.light} ${p.name} colour`});
			picker.addEventListener('input', () => {
				this.value = hexToColour(picker.value);
				this.show(picker);
				this.send(this.value.slice());
			});
			this.picker = picker;
			const triple = el('span', {class: 'triple'},
				this.numberField(0, 'red'), this.numberField(1, 'green'), this.numberField(2, 'blue'));
			row.append(this.label(id), picker, triple);
		} else {
			// point, vector, normal: x y z; a matrix: 16 fields, 4 a row.
			const n = Array.isArray(p.value) ? p.value.length : 1;
			const names = n === 3 ? ['x', 'y', 'z'] : null;
			const box = el('span', {class: n === 16 ? 'matrix' : 'triple'});
			for (let i = 0; i < n; i++)
				box.append(this.numberField(i, names ? names[i] : `${i}`));
			row.append(this.label(this.fields[0].id), box);
		}
		this.show();
		return row;
	}

	// Shows the value in every control but `except` (the one being moved).
	show(except = null) {
		const vals = Array.isArray(this.value) ? this.value : [this.value];
		this.fields.forEach((f, i) => {
			if (f !== except && document.activeElement !== f) {
				f.value = formatNumber(vals[i]);
				f.setAttribute('aria-invalid', 'false');
			}
		});
		if (this.slider && this.slider !== except) {
			const v = this.value;
			if (v < Number(this.slider.min) || v > Number(this.slider.max)) {
				const [lo, hi] = sliderRange(this.p, v);
				const min = Math.min(lo, v);
				const max = Math.max(hi, v);
				this.slider.min = String(min);
				this.slider.max = String(max);
				this.slider.step = String((max - min) / 1000);
			}
			this.slider.value = String(v);
		}
		if (this.picker && this.picker !== except)
			this.picker.value = colourToHex(this.value);
	}

	// A new value from the daemon (a reopened shot).
	update(p) {
		this.p = p;
		this.value = Array.isArray(p.value) ? p.value.slice() : p.value;
		this.show();
	}
}

// The light list. Callbacks: onParam(light, name, value), onSolo(light),
// onMute(light, on), onFreeze(light, on), onRemove(light).
export class LightPanel {
	constructor(container, callbacks) {
		this.container = container;
		this.cb = callbacks;
		this.cards = new Map();
		this.readOnly = false;
		this.solo = null;
		this.muted = new Set();
		this.frozen = new Set();
		this.collapsed = new Set();
		this.signature = '';
	}

	// The lights of an "opened" reply. The same lights with the same
	// parameters only update the values, leaving focus and layout alone.
	setLights(lights) {
		const sig = JSON.stringify(lights.map((l) => [l.name, l.shader, l.params.map((p) => [p.name, p.type])]));
		if (sig === this.signature) {
			for (const l of lights) {
				const card = this.cards.get(l.name);
				l.params.forEach((p, i) => card.controls[i].update(p));
			}
			return;
		}
		this.signature = sig;
		this.cards.clear();
		this.container.replaceChildren();
		for (const l of lights)
			this.container.append(this.card(l));
		for (const name of [...this.muted])
			if (!this.cards.has(name))
				this.muted.delete(name);
		for (const name of [...this.frozen])
			if (!this.cards.has(name))
				this.frozen.delete(name);
		if (this.solo !== null && !this.cards.has(this.solo))
			this.solo = null;
		this.refresh();
	}

	card(l) {
		const name = l.name;
		const bodyId = `light-${++uid}`;
		const caret = el('button', {type: 'button', class: 'caret', 'aria-expanded': 'true',
					    'aria-controls': bodyId, 'aria-label': `Show or hide light ${name}`});
		const toggle = (cls, text, title, fn) => {
			const b = el('button', {type: 'button', class: `tog ${cls}`, text, title,
						'aria-pressed': 'false', 'aria-label': `${title} light ${name}`});
			b.addEventListener('click', fn);
			return b;
		};
		const solo = toggle('solo', 'S', 'Solo', () => this.cb.onSolo(this.solo === name ? null : name));
		const mute = toggle('mute', 'M', 'Mute', () => this.cb.onMute(name, !this.muted.has(name)));
		const freeze = toggle('freeze', 'F', 'Freeze', () => this.cb.onFreeze(name, !this.frozen.has(name)));
		const remove = el('button', {type: 'button', class: 'tog remove', text: '\u00d7',
					     title: 'Remove', 'aria-label': `Remove light ${name}`});
		let armed = null;
		remove.addEventListener('click', () => {
			// Two clicks: the first arms the button for three seconds.
			if (armed) {
				clearTimeout(armed);
				armed = null;
				remove.classList.remove('armed');
				this.cb.onRemove(name);
				return;
			}
			remove.classList.add('armed');
			remove.title = 'Click again to remove';
			armed = setTimeout(() => {
				armed = null;
				remove.classList.remove('armed');
				remove.title = 'Remove';
			}, 3000);
		});
		const head = el('div', {class: 'light-head'}, caret,
			el('span', {class: 'lname', text: name}),
			el('span', {class: 'lshader', text: l.shader}),
			el('span', {class: 'tools'}, solo, mute, freeze, remove));
		const controls = l.params.map((p) => new ParamControl(name, p,
			(v) => this.cb.onParam(name, p.name, v)));
		const fields = el('fieldset', {class: 'params', id: bodyId},
			el('legend', {class: 'sr-only', text: `Parameters of light ${name}`}),
			...controls.map((c) => c.row));
		if (!controls.length)
			fields.append(el('div', {class: 'none', text: 'no parameters'}));
		const card = el('section', {class: 'light', 'aria-label': `Light ${name}, ${l.shader}`},
			head, fields);
		card.dataset.light = name;
		caret.addEventListener('click', () => {
			const open = caret.getAttribute('aria-expanded') !== 'true';
			caret.setAttribute('aria-expanded', String(open));
			fields.hidden = !open;
			if (open)
				this.collapsed.delete(name);
			else
				this.collapsed.add(name);
		});
		if (this.collapsed.has(name)) {
			caret.setAttribute('aria-expanded', 'false');
			fields.hidden = true;
		}
		this.cards.set(name, {card, fields, solo, mute, freeze, remove, controls});
		return card;
	}

	resetToggles() {
		this.solo = null;
		this.muted.clear();
		this.frozen.clear();
		this.refresh();
	}

	setReadOnly(on) {
		this.readOnly = on;
		this.refresh();
	}

	setSolo(name) {
		this.solo = name;
		this.refresh();
	}

	setMuted(name, on) {
		if (on)
			this.muted.add(name);
		else
			this.muted.delete(name);
		this.refresh();
	}

	setFrozen(name, on) {
		if (on)
			this.frozen.add(name);
		else
			this.frozen.delete(name);
		this.refresh();
	}

	refresh() {
		for (const [name, c] of this.cards) {
			c.fields.disabled = this.readOnly;
			for (const b of [c.solo, c.mute, c.freeze, c.remove])
				b.disabled = this.readOnly;
			c.solo.setAttribute('aria-pressed', String(this.solo === name));
			c.mute.setAttribute('aria-pressed', String(this.muted.has(name)));
			c.freeze.setAttribute('aria-pressed', String(this.frozen.has(name)));
			c.card.classList.toggle('muted', this.muted.has(name) ||
				(this.solo !== null && this.solo !== name));
			c.card.classList.toggle('frozen', this.frozen.has(name));
		}
	}

	// Marks the lights that reach a picked point (none: clears the marks).
	highlight(names) {
		const set = new Set(names || []);
		for (const [name, c] of this.cards)
			c.card.classList.toggle('reaches', set.has(name));
	}

	shaders() {
		return [...new Set([...this.cards.values()].map((c) =>
			c.card.querySelector('.lshader').textContent))];
	}
}
