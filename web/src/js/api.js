// The REST API (../shared/specs/rest.md) with the browser session's token.
// The token lives in sessionStorage only: it is gone when the tab closes.
const KEY = 'ambdiag.token';

export const token = {
  get: () => sessionStorage.getItem(KEY) || '',
  set: (t) => (t ? sessionStorage.setItem(KEY, t) : sessionStorage.removeItem(KEY)),
};

export class ApiError extends Error {
  constructor(status, message) {
    super(message);
    this.status = status;
  }
}

// A path segment as rest.md wants it ('/' in a run_id as %2F).
export const seg = (s) => encodeURIComponent(s);

async function call(method, path, body, as) {
  const headers = {};
  const t = token.get();
  if (t) headers.Authorization = 'Bearer ' + t;
  if (body !== undefined) headers['Content-Type'] = 'application/json';
  const r = await fetch(path, { method, headers, body: body === undefined ? undefined : JSON.stringify(body) });
  if (!r.ok) {
    let msg = r.status + ' ' + r.statusText;
    try {
      msg = (await r.json()).error || msg;
    } catch (_) { /* not JSON */ }
    throw new ApiError(r.status, msg);
  }
  if (as === 'text') return r.text();
  if (as === 'blob') return r.blob();
  return r.json();
}

export const get = (path) => call('GET', path);
export const getText = (path) => call('GET', path, undefined, 'text');
export const getBlob = (path) => call('GET', path, undefined, 'blob');
export const post = (path, body = {}) => call('POST', path, body);

// Routes that other features add (trends, alarms): a 404 "no such
// resource" means this server does not have them yet.
export const missingRoute = (e) => e instanceof ApiError && e.status === 404 && /no such resource/.test(e.message);

// Who the session is (GET /api/v1/me): {mode: 'token', name, role} for a
// token, {mode: 'anonymous', role: 'viewer'} where the server lets requests
// without one read (--anonymous-read), {mode: 'login'} otherwise. A refused
// token is dropped; `refused` says so, and `anonymousOk` whether the views
// could still open read-only.
export async function whoAmI() {
  const ask = async () => {
    try {
      return await get('/api/v1/me');
    } catch (e) {
      if (e instanceof ApiError && e.status === 401) return null;
      throw e;
    }
  };
  const hadToken = Boolean(token.get());
  let me = await ask();
  if (me) return { mode: me.anonymous ? 'anonymous' : 'token', name: me.name, role: me.role, anonymousOk: Boolean(me.anonymous) };
  if (!hadToken) return { mode: 'login', anonymousOk: false };
  token.set('');
  me = await ask();
  return { mode: 'login', refused: true, anonymousOk: Boolean(me) };
}
