// Headless Chromium for the web UI's tests and benchmarks: Debian's
// chromium (deploy/install-deps.sh) driven by playwright-core; nothing
// downloads a browser. AMBDIAG_CHROMIUM overrides the executable.
import { chromium } from 'playwright-core';
import { existsSync } from 'node:fs';

export const chromiumPath = process.env.AMBDIAG_CHROMIUM || '/usr/bin/chromium';

export async function launch() {
  if (!existsSync(chromiumPath)) throw new Error(`no chromium at ${chromiumPath} (deploy/install-deps.sh installs Debian's)`);
  // --no-sandbox: CI containers run as root, where Chromium's sandbox cannot start.
  return chromium.launch({ executablePath: chromiumPath, args: ['--no-sandbox', '--disable-gpu'] });
}

// Pixels of a canvas that are drawn (not transparent and not the
// background), counted in the page: proof a chart drew something.
export async function drawnPixels(page, selector) {
  return page.$eval(selector, (c) => {
    const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    let n = 0;
    for (let i = 0; i < d.length; i += 4) if (d[i + 3] > 0 && d[i] + d[i + 1] + d[i + 2] < 600) n++;
    return n;
  });
}
