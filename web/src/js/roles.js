// What the caller may do, from GET /api/v1/me: rest.md's roles, each with
// the rights of the ones before. An action above the caller's role is
// shown disabled with a tooltip naming the role it needs (so a viewer
// knows whom to ask, instead of a click answered 403); an anonymous reader
// (ambdiag serve --anonymous-read) sees no actions, and "Sign in" in the
// header instead.
import { h, esc } from './dom.js';

export const ROLES = ['viewer', 'operator', 'engineer', 'admin'];

// Whether the session's token has at least `role`.
export const can = (session, role) =>
  session.mode === 'token' && ROLES.indexOf(session.role) >= ROLES.indexOf(role);

// How an action that needs `role` shows: null (hidden: no token), {} (allowed)
// or {disabled, title} (the role is too low).
export function gate(session, role, what) {
  if (session.mode !== 'token') return null;
  if (can(session, role)) return {};
  return { disabled: true, title: `${what} needs the ${role} role; ${session.name} is ${session.role}` };
}

// A button of an HTML string rendered list, gated as above ('' when hidden).
export function gatedButton(session, role, what, attrs, label) {
  const g = gate(session, role, what);
  if (!g) return '';
  const extra = g.disabled ? ` disabled title="${esc(g.title)}"` : ` title="${esc(what)}"`;
  return `<button ${attrs}${extra}>${esc(label)}</button> `;
}

// Under a list of actions that need `role`, why they are missing or
// disabled: for an anonymous reader, that signing in brings them; for a
// token below the role, which role they need. null where they are allowed.
export function actionNote(session, role, what) {
  // operator and engineer: "an"
  if (session.mode === 'anonymous') return h('p', { class: 'muted role-note' }, `Read-only: sign in as an ${role} to ${what}.`);
  if (session.mode === 'token' && !can(session, role))
    return h('p', { class: 'muted role-note' }, `Only an ${role} (or above) can ${what}; ${session.name} is ${session.role}.`);
  return null;
}
