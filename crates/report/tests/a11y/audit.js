// Accessibility audit of the demo report: axe-core in headless Chromium (puppeteer-core), plus
// desktop (1280 px) and narrow (420 px) screenshots. Usage: node audit.js REPORT.html OUTDIR
// Exit 0: no serious/critical violations; 1: violations (listed); 2: could not run.
const path = require('path');
const fs = require('fs');
const puppeteer = require('puppeteer-core');
const axeSource = fs.readFileSync(require.resolve('axe-core/axe.min.js'), 'utf8');

(async () => {
  const [report, out] = process.argv.slice(2);
  const browser = await puppeteer.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    headless: true,
    args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage'],
  });
  try {
    const page = await browser.newPage();
    await page.setViewport({ width: 1280, height: 900 });
    await page.goto('file://' + path.resolve(report), { waitUntil: 'load' });
    await page.evaluate(axeSource);
    const res = await page.evaluate(async () => await axe.run(document, { resultTypes: ['violations'] }));
    await page.screenshot({ path: path.join(out, 'report-desktop.png'), fullPage: false });
    await page.screenshot({ path: path.join(out, 'report-desktop-full.png'), fullPage: true });
    await page.setViewport({ width: 420, height: 900 });
    await page.screenshot({ path: path.join(out, 'report-narrow.png'), fullPage: false });
    const bad = res.violations.filter((v) => v.impact === 'serious' || v.impact === 'critical');
    for (const v of res.violations) {
      console.log(`${v.impact}: ${v.id} (${v.nodes.length} nodes): ${v.help}`);
      for (const n of v.nodes.slice(0, 3)) console.log('   ', n.target.join(' '));
    }
    console.log(`axe-core ${res.testEngine.version}: ${res.violations.length} violations, ${bad.length} serious/critical`);
    process.exitCode = bad.length ? 1 : 0;
  } finally {
    await browser.close();
  }
})().catch((e) => {
  console.error('audit could not run:', e);
  process.exit(2);
});
