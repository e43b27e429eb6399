// FRF files (ambdiag.frf/1, ../shared/specs/frf-file.md) parsed in the
// browser: metadata, the frequency grid and each entry's complex values.
export function parseFrf(text) {
  const lines = text.split('\n');
  const meta = {};
  let i = 0;
  for (; i < lines.length && lines[i].startsWith('#'); i++) {
    const m = /^#\s*([^:]+):\s*(.*)$/.exec(lines[i]);
    if (m) meta[m[1].trim()] = m[2].trim();
  }
  const header = lines[i++].trim().split(',');
  const rows = [];
  for (; i < lines.length; i++) if (lines[i].length > 1) rows.push(lines[i]);
  const cols = header.map(() => new Float64Array(rows.length));
  rows.forEach((line, r) => {
    const parts = line.split(',');
    for (let c = 0; c < cols.length; c++) cols[c][r] = +parts[c];
  });
  const byName = new Map(header.map((h, c) => [h, cols[c]]));
  const entries = [];
  for (const h of header) {
    const m = /^H_(.+)_(.+)_re$/.exec(h);
    if (m) entries.push({ output: m[1], input: m[2] });
  }
  return { meta, f: byName.get('freq_hz'), byName, entries };
}

// Magnitude and phase (degrees) of one entry; null when the file lacks it.
export function entryMagPhase(frf, output, input) {
  const re = frf.byName.get(`H_${output}_${input}_re`);
  const im = frf.byName.get(`H_${output}_${input}_im`);
  if (!re || !im) return null;
  const mag = new Float64Array(re.length);
  const phase = new Float64Array(re.length);
  for (let k = 0; k < re.length; k++) {
    mag[k] = Math.hypot(re[k], im[k]);
    phase[k] = (Math.atan2(im[k], re[k]) * 180) / Math.PI;
  }
  return { mag, phase };
}
