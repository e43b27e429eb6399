// The shell: login, hash routing over the hierarchy fleet -> pump -> run
// (and the alarm list), the crumbs, and the live event stream that the
// current view listens to.
import { token, whoAmI, get } from './api.js';
import { $, esc, errorBox, debounce } from './dom.js';
import { Live } from './live.js';
import { fleetView } from './fleet.js';
import { pumpView } from './pump.js';
import { runView } from './run.js';
import { alarmsView } from './alarms.js';
import { loginView } from './login.js';

const live = new Live($('#live'));
let current = null; // the view shown: {dispose?, onEvent?}
// Who is signed in (api.js whoAmI): mode 'token' | 'anonymous' | 'login',
// name and role; the views offer the actions of that role (roles.js).
export const session = { mode: 'login' };
let afterSignIn = ''; // the view to return to once signed in

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

// Each route renders into a container of its own, which the next route
// replaces: a slow view (a run's FRFs) that finishes after the user moved
// on writes into its detached container, not into the page shown, and is
// disposed.
let routeSeq = 0;
async function route() {
  const seq = ++routeSeq;
  current?.dispose?.();
  current = null;
  const { name, arg } = parseHash();
  for (const a of document.querySelectorAll('[data-nav]')) a.classList.toggle('active', a.dataset.nav === name);
  if (session.mode === 'login' && name !== 'login') {
    afterSignIn = location.hash; // a deep link (a run, a pump) opens once signed in
    location.hash = '#/login';
    return;
  }
  const main = document.createElement('div');
  $('#view').replaceChildren(main);
  const ctx = { main, crumbs: (parts) => seq === routeSeq && crumbs(parts), session, live };
  let shown = null;
  try {
    if (name === 'login') shown = loginView(ctx, start);
    else if (name === 'pump') shown = await pumpView(ctx, arg);
    else if (name === 'run') shown = await runView(ctx, arg);
    else if (name === 'alarms') shown = await alarmsView(ctx);
    else shown = await fleetView(ctx);
  } catch (e) {
    main.append(errorBox(e));
  }
  if (seq !== routeSeq) return shown?.dispose?.();
  current = shown;
  $('#view').focus();
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
    session.mode === 'anonymous' ? 'read-only (not signed in)' : session.mode === 'token' ? `${session.name} (${session.role})` : '';
  $('#who').title = session.mode === 'token' ? `signed in as ${session.name}, role ${session.role}` : '';
  $('#logout').hidden = session.mode !== 'token';
  $('#login').hidden = session.mode !== 'anonymous';
}

// Decides between the login page and the views: with --anonymous-read the
// views open read-only without a token, and "Sign in" offers the rest.
async function start() {
  let who;
  try {
    who = await whoAmI();
  } catch (e) {
    $('#view').replaceChildren(errorBox(e));
    return;
  }
  for (const k of ['name', 'role', 'refused', 'anonymousOk']) delete session[k];
  Object.assign(session, who);
  showWho();
  if (session.mode === 'login') {
    live.stop();
    route(); // the login page; route() keeps the link asked for
    return;
  }
  live.start(token.get(), (ev) => {
    current?.onEvent?.(ev);
    alarmBadge();
  });
  alarmBadge();
  if (location.hash === '#/login' || !location.hash) location.hash = afterSignIn || '#/fleet';
  else route();
  afterSignIn = '';
}

$('#logout').addEventListener('click', () => {
  token.set('');
  start();
});
$('#login').addEventListener('click', () => {
  afterSignIn = location.hash;
  location.hash = '#/login';
});
window.addEventListener('hashchange', route);
start();
