#!/usr/bin/env node
// Drives revolve's web console in a real browser (Debian's chromium, headless, through
// puppeteer-core): loads the page, presses Start, waits until every stop is shown as done and the
// finished model is in the viewer, checks that the viewer's canvas draws (non-background pixels
// read back from WebGL), and saves a screenshot.
//   node console_browser.js URL SCREENSHOT.png [STOPS]
// Prints a JSON report on stdout. Exit status: 0 pass, 1 a check failed, 3 the browser cannot run
// here (the caller skips).
'use strict';
const fs = require('fs');
const os = require('os');
const path = require('path');

const [url, screenshot, stopsArg] = process.argv.slice(2);
const stops = Number(stopsArg || 36);
const chromium = process.env.CHROMIUM || '/usr/bin/chromium';

function cannotRun(why) {
  console.log(JSON.stringify({ skipped: why }));
  process.exit(3);
}

async function main() {
  let puppeteer;
  try {
    puppeteer = require(path.join(__dirname, 'node_modules', 'puppeteer-core'));
  } catch (e) {
    cannotRun('puppeteer-core is not installed (npm ci --prefix tests/tools): ' + e.message);
  }
  if (!fs.existsSync(chromium)) cannotRun(chromium + ' does not exist (apt install chromium)');
  const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'revolve-chromium-'));
  let browser;
  try {
    browser = await puppeteer.launch({
      executablePath: chromium,
      headless: true,
      userDataDir: profile,
      args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
        '--disable-background-networking', '--disable-component-update', '--disable-sync',
        '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
        '--window-size=1280,1600'],
      timeout: 60000,
    });
  } catch (e) {
    fs.rmSync(profile, { recursive: true, force: true });
    cannotRun('chromium does not start here: ' + e.message);
  }
  const report = { url, stops };
  const consoleErrors = [];
  try {
    const page = await browser.newPage();
    await page.setViewport({ width: 1280, height: 1600 });
    page.on('pageerror', (e) => consoleErrors.push(String(e)));
    // Chromium reports a failed request as a console error without its URL: the responses say
    // which. The live frame and hull answer 404 until the first stop is saved and meshed.
    page.on('console', (m) => {
      if (m.type() === 'error' && !m.text().startsWith('Failed to load resource')) consoleErrors.push(m.text());
    });
    page.on('response', (r) => {
      if (r.status() >= 400 && !new URL(r.url()).pathname.startsWith('/api/live/')) {
        consoleErrors.push(r.status() + ' ' + r.url());
      }
    });
    await page.goto(url, { waitUntil: 'load', timeout: 30000 });
    await page.waitForFunction(() => window.revolve && !document.getElementById('start').disabled,
        { timeout: 30000 });
    report.webgl = await page.evaluate(() => window.revolve.viewerPixels() !== null);
    await page.click('#start');
    // The hull grows while the stops come in.
    await page.waitForFunction(() => /live hull/.test(document.getElementById('viewer-caption').textContent),
        { timeout: 60000 }).then(() => { report.live_hull_seen = true; }, () => { report.live_hull_seen = false; });
    await page.waitForFunction((n) => document.querySelectorAll('#stops span.done').length === n &&
        document.getElementById('state').dataset.state === 'done', { timeout: 180000 }, stops);
    report.stops_done_cells = await page.evaluate(() => document.querySelectorAll('#stops span.done').length);
    report.frame_shown = await page.evaluate(() => !document.getElementById('frame').hidden &&
        document.getElementById('frame').naturalWidth > 0);
    // The finished model in the viewer, and the report's figures and links.
    await page.waitForFunction(() => !document.getElementById('report-card').hidden &&
        document.querySelectorAll('#downloads a').length > 0, { timeout: 30000 });
    report.downloads = await page.evaluate(() => [...document.querySelectorAll('#downloads a')].map((a) => a.textContent));
    report.figures = await page.evaluate(() => [...document.querySelectorAll('#report dt')].map((d) => d.textContent));
    // The scans list and its thumbnail load after the report (on a loaded machine, seconds
    // after): waited for, then read; a thumbnail that never loads reads false.
    const thumbnailLoaded = () => {
      const img = document.querySelector('#scans li img');
      return !!img && img.complete && img.naturalWidth > 0;
    };
    await page.waitForFunction(thumbnailLoaded, { timeout: 30000 }).catch(() => {});
    report.scans_listed = await page.evaluate(() => document.querySelectorAll('#scans li').length);
    report.thumbnail = await page.evaluate(() => {
      const img = document.querySelector('#scans li img');
      return !!img && img.complete && img.naturalWidth > 0;
    });
    if (report.webgl) {
      await page.waitForFunction(() => !/live hull/.test(document.getElementById('viewer-caption').textContent) &&
          document.getElementById('viewer-caption').textContent.length > 0, { timeout: 30000 });
      await new Promise((r) => setTimeout(r, 500));
      report.viewer = await page.evaluate(() => window.revolve.viewerPixels());
    }
    // A phone: the page fits a 390 px wide screen without sideways scrolling.
    await page.setViewport({ width: 390, height: 844, isMobile: true, hasTouch: true, deviceScaleFactor: 2 });
    await new Promise((r) => setTimeout(r, 300));
    report.phone_overflow_px = await page.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
    await page.setViewport({ width: 1280, height: 1600 });
    await new Promise((r) => setTimeout(r, 300));
    await page.screenshot({ path: screenshot, fullPage: true });
    report.screenshot = screenshot;
  } catch (e) {
    report.error = String(e && e.stack || e);
  } finally {
    report.console_errors = consoleErrors;
    await browser.close();
    fs.rmSync(profile, { recursive: true, force: true });
  }
  console.log(JSON.stringify(report, null, 2));
  const ok = !report.error && report.stops_done_cells === stops && consoleErrors.length === 0 &&
      (!report.webgl || (report.viewer && report.viewer.differ > 100));
  process.exit(ok ? 0 : 1);
}

main().catch((e) => { console.log(JSON.stringify({ error: String(e) })); process.exit(1); });
