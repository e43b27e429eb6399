// The server's event stream (GET /api/v1/events, server-sent events). A
// browser's EventSource cannot send headers, so the token goes as
// ?access_token=; the browser reconnects by itself with Last-Event-ID.
const TYPES = ['run.new', 'run.status', 'job.done', 'job.failed', 'model.new', 'reference.new', 'alarm.transition', 'reload'];

export class Live {
  constructor(indicator) {
    this.el = indicator;
    this.source = null;
  }

  start(tok, onEvent) {
    this.stop();
    const url = '/api/v1/events' + (tok ? '?access_token=' + encodeURIComponent(tok) : '');
    const es = new EventSource(url);
    this.source = es;
    this.show(false);
    es.onopen = () => this.show(true);
    es.onerror = () => this.show(false);
    const deliver = (type) => (m) => {
      let data = {};
      try {
        data = JSON.parse(m.data);
      } catch (_) { /* keep {} */ }
      onEvent({ type, data });
    };
    for (const t of TYPES) es.addEventListener(t, deliver(t));
  }

  stop() {
    this.source?.close();
    this.source = null;
    this.show(false);
  }

  show(on) {
    this.el.textContent = on ? 'live' : 'live: off';
    this.el.className = 'live ' + (on ? 'on' : 'off');
  }
}
