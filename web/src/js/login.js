// Sign in with a token from `ambdiag token add`; it is kept for this
// browser tab only (sessionStorage).
import { token } from './api.js';
import { h } from './dom.js';

export function loginView({ main, crumbs, session }, onSignedIn) {
  crumbs([['Sign in']]);
  const input = h('input', { type: 'password', id: 'token', autocomplete: 'off', placeholder: 'token', 'aria-label': 'token' });
  const msg = session.refused
    ? h('p', { class: 'error' }, 'The token was refused (unknown or revoked).')
    : h('p', { class: 'muted' }, 'A token from `ambdiag token add`. It is kept for this browser tab only.');
  // Where the server lets requests without a token read (--anonymous-read).
  const readOnly =
    session.mode === 'anonymous' || session.anonymousOk
      ? h('p', {}, h('button', { type: 'button', id: 'read-only', onclick: () => onSignedIn() }, 'Continue read-only, without signing in'))
      : null;
  const form = h(
    'form',
    {
      class: 'panel login',
      onsubmit: (e) => {
        e.preventDefault();
        token.set(input.value.trim());
        onSignedIn();
      },
    },
    h('h1', {}, 'Sign in'),
    input,
    h('button', { type: 'submit', id: 'sign-in' }, 'Sign in'),
    msg,
    readOnly,
  );
  main.append(form);
  input.focus();
  return {};
}
