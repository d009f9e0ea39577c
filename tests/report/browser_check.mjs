// Opens a tirstrain report in headless Chromium (Debian's /usr/bin/chromium) and checks that it renders:
// no console error or page error, every expected <figure> present and drawn (a non-empty SVG, or a canvas
// with non-blank pixels), and a full-page screenshot that is not blank.
// Usage: node browser_check.mjs REPORT.html SCREENSHOT.png FIGURE_ID...
// Prints one line per check; exit 0 when all pass, 1 otherwise, 77 when no Chromium is installed.
import { existsSync } from 'node:fs';
import { createRequire } from 'node:module';
import { pathToFileURL } from 'node:url';

const require = createRequire(import.meta.url);
const here = new URL('.', import.meta.url).pathname;
const { chromium } = require(here + '../../report/web/node_modules/playwright-core');

const [report, screenshot, ...expected] = process.argv.slice(2);
const executable = process.env.TIRSTRAIN_CHROMIUM || '/usr/bin/chromium';
if (!existsSync(executable)) {
  console.log(`skipped: no Chromium at ${executable}`);
  process.exit(77);
}

const failures = [];
const check = (ok, what) => {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}`);
  if (!ok) failures.push(what);
};

const browser = await chromium.launch({
  executablePath: executable,
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
         '--disable-component-update', '--disable-sync'],
});
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 900 } });
  const problems = [];
  page.on('console', (m) => { if (m.type() === 'error' || m.type() === 'warning') problems.push(`console ${m.type()}: ${m.text()}`); });
  page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
  page.on('request', (r) => { if (!r.url().startsWith('file:') && !r.url().startsWith('data:')) problems.push(`network request: ${r.url()}`); });
  await page.goto(pathToFileURL(report).href);
  await page.waitForFunction(() => document.body.hasAttribute('data-rendered') || document.body.hasAttribute('data-render-error'),
                             null, { timeout: 60000 });
  const error = await page.getAttribute('body', 'data-render-error');
  check(error === null, `every figure drawn${error ? ': ' + error : ''}`);
  for (const id of expected) {
    const state = await page.evaluate((id) => {
      const f = document.getElementById(id);
      if (!f) return 'missing';
      if (f.tagName !== 'FIGURE' || !f.querySelector('figcaption') || !f.querySelector('figcaption').textContent.trim()) return 'no caption';
      const canvas = f.querySelector('.plot canvas');
      const svg = f.querySelector('.plot svg.marks');
      if (svg) {
        // Marks with a drawn extent, not just present: an arc or line of zero size draws nothing.
        const marks = [...svg.querySelectorAll('g.mark-arc path, g.mark-line path, g.mark-rect path, g.mark-symbol path')];
        const visible = marks.filter((m) => { const b = m.getBBox(); return b.width > 1 || b.height > 1; });
        return visible.length > 10 ? 'drawn' : `empty svg (${visible.length} visible marks)`;
      }
      if (canvas) {
        const c = canvas.getContext('2d').getImageData(0, 0, canvas.width, canvas.height).data;
        let coloured = 0;
        for (let i = 0; i < c.length; i += 4) if (c[i + 3] > 0 && (c[i] < 235 || c[i + 1] < 235 || c[i + 2] < 235)) ++coloured;
        return coloured > 1000 ? 'drawn' : 'blank canvas';
      }
      return f.querySelector('table') ? 'drawn' : 'no plot';
    }, id);
    check(state === 'drawn', `figure ${id}: ${state}`);
  }
  const buffer = await page.screenshot({ path: screenshot, fullPage: true });
  // A blank page compresses to almost nothing; a drawn one holds many distinct colours.
  const colours = await page.evaluate(async (b64) => {
    const img = new Image();
    img.src = 'data:image/png;base64,' + b64;
    await img.decode();
    const c = document.createElement('canvas');
    c.width = img.width; c.height = Math.min(img.height, 8000);
    const g = c.getContext('2d');
    g.drawImage(img, 0, 0);
    const d = g.getImageData(0, 0, c.width, c.height).data;
    const seen = new Set();
    let dark = 0;
    for (let i = 0; i < d.length; i += 16) { seen.add((d[i] << 16) | (d[i + 1] << 8) | d[i + 2]); if (d[i] + d[i + 1] + d[i + 2] < 600) ++dark; }
    return { distinct: seen.size, dark_fraction: dark / (d.length / 16) };
  }, buffer.toString('base64'));
  check(colours.distinct > 200 && colours.dark_fraction > 0.01,
        `screenshot not blank: ${colours.distinct} distinct colours, ${(100 * colours.dark_fraction).toFixed(1)} % non-white pixels`);
  for (const p of problems) check(false, p);
} finally {
  await browser.close();
}
process.exit(failures.length ? 1 : 0);
