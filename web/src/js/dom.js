// Small DOM and formatting helpers (no framework: the views are few and
// the long lists are rendered as one HTML string, the fastest way).
export const $ = (sel, root = document) => root.querySelector(sel);

const ESC = { '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;', "'": '&#39;' };
export const esc = (s) => String(s ?? '').replace(/[&<>"']/g, (c) => ESC[c]);

// h('a', {href: '#'}, 'text', child): an element; attributes starting with
// "on" are listeners.
export function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === undefined || v === null || v === false) continue;
    if (k.startsWith('on')) el.addEventListener(k.slice(2), v);
    else if (k === 'class') el.className = v;
    else if (k === 'html') el.innerHTML = v;
    else el.setAttribute(k, v === true ? '' : v);
  }
  for (const c of children.flat()) if (c !== null && c !== undefined && c !== false) el.append(c instanceof Node ? c : String(c));
  return el;
}

export function fmtTime(iso) {
  if (!iso) return '–';
  const d = new Date(iso);
  if (Number.isNaN(d.getTime())) return iso;
  return d.toISOString().replace('T', ' ').replace(/\.\d+Z$|Z$/, ' UTC');
}

export function fmtNum(x, digits = 3) {
  if (x === null || x === undefined || Number.isNaN(x)) return '–';
  if (typeof x !== 'number') return String(x);
  const a = Math.abs(x);
  // Trailing zeros of the fraction only ("1.8000" -> "1.8", "2.19e+5", "100" stays).
  if (a !== 0 && (a < 1e-3 || a >= 1e5)) return x.toExponential(digits - 1).replace(/\.?0+e/, 'e');
  const t = x.toPrecision(digits);
  return t.includes('.') ? t.replace(/\.?0+$/, '') : t;
}

// Health as ISA-101 wants it: a word and a symbol, coloured only when abnormal.
const HEALTH = {
  ok: ['OK', 'st-ok', ''],
  warning: ['WARNING', 'st-warning', '◆ '],
  alarm: ['ALARM', 'st-alarm', '▲ '],
  unknown: ['UNKNOWN', 'st-unknown', '? '],
};
// `quiet`: the word in grey, for a count of zero (nothing abnormal to show).
export function healthHtml(health, quiet = false) {
  const [word, cls, sym] = HEALTH[health] || HEALTH.unknown;
  return `<span class="st ${quiet ? 'st-quiet' : cls}" data-health="${esc(health)}">${sym}${word}</span>`;
}

const SEV_SYM = { critical: '▲▲ ', high: '▲ ', medium: '◆ ', low: '▽ ' };
export const sevHtml = (s, quiet = false) =>
  `<span class="sev ${quiet ? 'st-quiet' : 'sev-' + esc(s)}">${SEV_SYM[s] || ''}${esc(String(s).toUpperCase())}</span>`;

export function toast(msg, ms = 4000) {
  const box = document.getElementById('toast');
  const d = h('div', {}, msg);
  box.append(d);
  setTimeout(() => d.remove(), ms);
}

export const errorBox = (e) => h('p', { class: 'error' }, e.message || String(e));

// fn after `ms` without another call (live events come in bursts); .cancel().
export function debounce(fn, ms) {
  let timer = null;
  const d = () => {
    clearTimeout(timer);
    timer = setTimeout(fn, ms);
  };
  d.cancel = () => clearTimeout(timer);
  return d;
}
