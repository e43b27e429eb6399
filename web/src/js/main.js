// The shell: login, hash routing over the hierarchy fleet -> pump -> run
// (and the alarm list), the crumbs, and the live event stream that the
// current view listens to.
import { token, probe, get } from './api.js';
import { $, esc, errorBox, debounce } from './dom.js';
import { Live } from './live.js';
import { fleetView } from './fleet.js';
import { pumpView } from './pump.js';
import { runView } from './run.js';
import { alarmsView } from './alarms.js';
import { loginView } from './login.js';

const live = new Live($('#live'));
let current = null; // the view shown: {dispose?, onEvent?}
export const session = { mode: 'login' }; // 'token' | 'anonymous' | 'login'

function crumbs(parts) {
  const nav = $('#crumbs');
  nav.innerHTML = parts
    .map(([label, href]) => (href ? `<a href="${esc(href)}">${esc(label)}</a>` : `<span>${esc(label)}</span>`))
    .join('<span class="sep">›</span>');
}

function parseHash() {
  const [, name = 'fleet', ...rest] = location.hash.replace(/^#/, '').split('/');
  return { name, arg: rest.map(decodeURIComponent).join('/') };
}

async function route() {
  current?.dispose?.();
  current = null;
  const main = $('#view');
  const { name, arg } = parseHash();
  for (const a of document.querySelectorAll('[data-nav]')) a.classList.toggle('active', a.dataset.nav === name);
  if (session.mode === 'login' && name !== 'login') {
    location.hash = '#/login';
    return;
  }
  const ctx = { main, crumbs, session, live };
  main.replaceChildren();
  try {
    if (name === 'login') current = loginView(ctx, start);
    else if (name === 'pump') current = await pumpView(ctx, arg);
    else if (name === 'run') current = await runView(ctx, arg);
    else if (name === 'alarms') current = await alarmsView(ctx);
    else current = await fleetView(ctx);
  } catch (e) {
    main.append(errorBox(e));
  }
  main.focus();
}

// The header's badge: alarms not yet acknowledged (where the server has alarms).
const alarmBadge = debounce(async () => {
  const el = $('#alarm-count');
  try {
    const { alarms } = await get('/api/v1/alarms');
    const n = alarms.filter((a) => String(a.state).startsWith('unack')).length;
    el.textContent = n ? `▲ ${n}` : '';
    el.hidden = n === 0;
  } catch (_) {
    el.hidden = true;
  }
}, 300);

function showWho() {
  document.body.classList.toggle('signed-out', session.mode === 'login');
  $('#who').textContent =
    session.mode === 'anonymous' ? 'read-only (no token)' : session.mode === 'token' ? 'signed in' : '';
  $('#logout').hidden = session.mode !== 'token';
}

// Decides between the login page and the views: with --anonymous-read the
// views open read-only without a token.
async function start() {
  try {
    session.mode = await probe();
  } catch (e) {
    $('#view').replaceChildren(errorBox(e));
    return;
  }
  showWho();
  if (session.mode === 'login') {
    live.stop();
    if (location.hash !== '#/login') location.hash = '#/login';
    else route();
    return;
  }
  live.start(token.get(), (ev) => {
    current?.onEvent?.(ev);
    alarmBadge();
  });
  alarmBadge();
  if (location.hash === '#/login' || !location.hash) location.hash = '#/fleet';
  else route();
}

$('#logout').addEventListener('click', () => {
  token.set('');
  start();
});
window.addEventListener('hashchange', route);
start();
