#!/usr/bin/env node
// Open a deckpose MCAP log with a Foxglove layout in Foxglove Studio 1.48.0 (the npm package
// @foxglove/studio-base's browser bundle) under headless Chromium, and record what a person sees:
// a screenshot, the page's text, each panel's place and text, and the viewer's problems list.
//
// Usage: node view.mjs LOG.mcap LAYOUT.json OUT_DIR [--width 1600] [--height 1000] [--timeout-s 60]
//                      [--settle-s 4] [--time RFC3339]
// Writes OUT_DIR/screenshot.png, OUT_DIR/page.txt and OUT_DIR/report.json; exits 0 when the page
// loaded the log (whatever the panels show: judging them is the caller's job), 1 when it did not,
// 2 on bad usage. Needs node >= 18, this folder's packages (npm ci) and a Chromium:
// $CHROMIUM, or chromium-headless-shell / chromium on PATH.
//
// The log is served by a small HTTP server on 127.0.0.1 that answers Range requests, which the
// app's remote-file source needs (it reads an indexed MCAP file in pieces).

import { spawn } from "node:child_process";
import { createReadStream, existsSync } from "node:fs";
import { mkdir, mkdtemp, rm, stat, writeFile } from "node:fs/promises";
import { createServer } from "node:http";
import { tmpdir } from "node:os";
import { delimiter, dirname, extname, join, resolve, sep } from "node:path";
import { fileURLToPath } from "node:url";

import WebSocket from "ws";

const HERE = dirname(fileURLToPath(import.meta.url));
const TYPES = {
  ".html": "text/html", ".js": "text/javascript", ".json": "application/json", ".wasm": "application/wasm",
  ".png": "image/png", ".ttf": "font/ttf", ".woff2": "font/woff2", ".svg": "image/svg+xml",
  ".mcap": "application/octet-stream",
};

function usage(msg) {
  console.error(`view.mjs: ${msg}\nusage: node view.mjs LOG.mcap LAYOUT.json OUT_DIR [--width W] [--height H] [--timeout-s S] [--settle-s S] [--time RFC3339]`);
  process.exit(2);
}

function parseArgs(argv) {
  const pos = [];
  const opt = { width: 1600, height: 1000, timeoutS: 60, settleS: 4, time: undefined };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    if (!a.startsWith("--")) { pos.push(a); continue; }
    const v = argv[++i];
    if (v == undefined) usage(`${a} needs a value`);
    if (a === "--width") opt.width = Number(v);
    else if (a === "--height") opt.height = Number(v);
    else if (a === "--timeout-s") opt.timeoutS = Number(v);
    else if (a === "--settle-s") opt.settleS = Number(v);
    else if (a === "--time") opt.time = v;
    else usage(`unknown option ${a}`);
  }
  if (pos.length !== 3) usage("needs LOG.mcap LAYOUT.json OUT_DIR");
  for (const k of ["width", "height", "timeoutS", "settleS"]) {
    if (!Number.isFinite(opt[k]) || opt[k] <= 0) usage(`--${k} must be a positive number`);
  }
  return { log: resolve(pos[0]), layout: resolve(pos[1]), out: resolve(pos[2]), ...opt };
}

function findChromium() {
  if (process.env.CHROMIUM) return process.env.CHROMIUM;
  for (const name of ["chromium-headless-shell", "chromium", "chromium-browser", "google-chrome"]) {
    for (const dir of (process.env.PATH ?? "").split(delimiter)) {
      const p = join(dir, name);
      if (dir && existsSync(p)) return p;
    }
  }
  return undefined;
}

// ---------------------------------------------------------------------------------------------
// A static file server that answers single Range requests (206 with Content-Range).

function serve(routes) {
  // routes: URL path -> file path, and "/" prefix -> HERE for the page and its packages.
  const server = createServer(async (req, res) => {
    try {
      const url = new URL(req.url ?? "/", "http://localhost");
      let file = routes.get(url.pathname);
      if (file == undefined) {
        file = resolve(HERE, "." + decodeURIComponent(url.pathname));
        if (file !== HERE && !file.startsWith(HERE + sep)) { res.writeHead(403).end(); return; }
      }
      const info = await stat(file).catch(() => undefined);
      if (info == undefined || !info.isFile()) { res.writeHead(404).end(); return; }
      const headers = { "Content-Type": TYPES[extname(file)] ?? "application/octet-stream",
        "Accept-Ranges": "bytes", "Cache-Control": "no-store" };
      const range = /^bytes=(\d*)-(\d*)$/.exec(req.headers.range ?? "");
      let start = 0;
      let end = info.size - 1;
      let status = 200;
      if (req.headers.range != undefined) {
        if (range == undefined || (range[1] === "" && range[2] === "")) {
          res.writeHead(416, { "Content-Range": `bytes */${info.size}` }).end();
          return;
        }
        if (range[1] === "") { start = Math.max(0, info.size - Number(range[2])); }
        else { start = Number(range[1]); end = range[2] === "" ? end : Math.min(end, Number(range[2])); }
        if (start > end || start >= info.size) {
          res.writeHead(416, { "Content-Range": `bytes */${info.size}` }).end();
          return;
        }
        status = 206;
        headers["Content-Range"] = `bytes ${start}-${end}/${info.size}`;
      }
      headers["Content-Length"] = String(end - start + 1);
      res.writeHead(status, headers);
      if (req.method === "HEAD" || info.size === 0) { res.end(); return; }
      createReadStream(file, { start, end }).pipe(res);
    } catch (err) {
      res.writeHead(500).end(String(err));
    }
  });
  return new Promise((ok) => server.listen(0, "127.0.0.1", () => ok(server)));
}

// ---------------------------------------------------------------------------------------------
// A minimal Chrome DevTools Protocol client over one browser WebSocket (flat sessions).

class Cdp {
  constructor(ws) {
    this.ws = ws;
    this.next = 1;
    this.pending = new Map();
    this.handlers = [];
    ws.on("message", (data) => {
      const msg = JSON.parse(String(data));
      if (msg.id != undefined && this.pending.has(msg.id)) {
        const { ok, fail, method } = this.pending.get(msg.id);
        this.pending.delete(msg.id);
        if (msg.error) fail(new Error(`${method}: ${msg.error.message}`));
        else ok(msg.result);
      } else if (msg.method) {
        for (const h of this.handlers) h(msg);
      }
    });
  }
  send(method, params = {}, sessionId = undefined) {
    const id = this.next++;
    this.ws.send(JSON.stringify({ id, method, params, ...(sessionId ? { sessionId } : {}) }));
    return new Promise((ok, fail) => this.pending.set(id, { ok, fail, method }));
  }
  on(handler) { this.handlers.push(handler); }
}

// Chromium runs in its own process group (launch); this ends the group: the browser and its
// zygote, GPU and renderer processes (a SIGKILL of the browser process alone left them running).
function killGroup(child) {
  try {
    process.kill(-child.pid, "SIGKILL");
  } catch {
    child.kill("SIGKILL");
  }
}

function launch(chromium, userDir, width, height) {
  const args = [
    "--headless", "--remote-debugging-port=0", `--user-data-dir=${userDir}`, "--no-first-run",
    "--no-default-browser-check", "--disable-gpu-sandbox", "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist", "--enable-webgl", `--window-size=${width},${height}`,
    "--hide-scrollbars", "--mute-audio", "--disable-background-timer-throttling",
    "--disable-renderer-backgrounding", "--disable-backgrounding-occluded-windows",
  ];
  if (process.getuid?.() === 0) args.push("--no-sandbox");
  // its own process group (killGroup)
  const child = spawn(chromium, [...args, "about:blank"], { stdio: ["ignore", "ignore", "pipe"], detached: true });
  return new Promise((ok, fail) => {
    let err = "";
    const timer = setTimeout(() => {
      killGroup(child);
      fail(new Error(`chromium did not start in 30 s:\n${err}`));
    }, 30_000);
    child.stderr.on("data", (d) => {
      err += String(d);
      const m = /DevTools listening on (ws:\/\/\S+)/.exec(err);
      if (m) { clearTimeout(timer); ok({ child, wsUrl: m[1] }); }
    });
    child.on("exit", (code) => { clearTimeout(timer); fail(new Error(`chromium exited (${code}):\n${err}`)); });
  });
}

const sleep = (ms) => new Promise((ok) => setTimeout(ok, ms));

// Runs in the page: every panel's id, place and text; the app's state.
function pageState() {
  const panels = [];
  for (const win of document.querySelectorAll(".mosaic-window")) {
    const r = win.getBoundingClientRect();
    const root = win.querySelector("[data-testid^='panel-mouseenter-container']");
    const id = root ? root.getAttribute("data-testid").replace("panel-mouseenter-container", "").trim() : "";
    const header = win.querySelector("[data-testid='mosaic-drag-handle']");
    const h = header ? header.getBoundingClientRect() : { bottom: r.top };
    panels.push({
      id,
      title: header ? header.innerText.trim() : "",
      rect: [r.left, r.top, r.width, r.height],
      // The panel's drawing area: below its toolbar.
      body: [r.left, h.bottom, r.width, r.bottom - h.bottom],
      text: win.innerText,
      canvases: [...win.querySelectorAll("canvas")].map((c) => {
        const cr = c.getBoundingClientRect();
        return [cr.left, cr.top, cr.width, cr.height];
      }),
    });
  }
  return {
    mounted: window.__deckpose?.mounted ?? false,
    errors: window.__deckpose?.errors ?? [],
    text: document.body.innerText,
    panels,
  };
}

// Runs in the page: opens the data source sidebar's Problems tab and reads its list.
async function readProblems() {
  const tab = [...document.querySelectorAll("[role='tab']")].find((t) => t.innerText.trim().startsWith("Problems"));
  if (!tab) return { tab: false, count: 0, items: [], text: "" };
  tab.click();
  await new Promise((ok) => setTimeout(ok, 500));
  // DataSourceSidebar: a column of [tabs, divider, tab content].
  const tabs = tab.closest(".MuiTabs-root");
  const content = tabs?.parentElement?.lastElementChild;
  const items = content ? [...content.querySelectorAll("li")].map((li) => li.innerText.trim()) : [];
  const badge = tab.innerText.replace("Problems", "").trim();
  return { tab: true, count: badge === "" ? 0 : Number(badge), items, text: content ? content.innerText.trim() : "" };
}

async function main() {
  const opt = parseArgs(process.argv.slice(2));
  const chromium = findChromium();
  if (chromium == undefined) {
    console.error("view.mjs: no Chromium found: set CHROMIUM or install chromium-headless-shell (apt-get install chromium-headless-shell)");
    process.exit(2);
  }
  for (const f of [opt.log, opt.layout]) {
    if (!existsSync(f)) usage(`no such file ${f}`);
  }
  if (!existsSync(join(HERE, "node_modules", "@foxglove", "studio-base", "assets", "index.js"))) {
    usage(`the viewer's packages are not installed: npm ci --prefix ${HERE}`);
  }
  await mkdir(opt.out, { recursive: true });
  const server = await serve(new Map([["/data/log.mcap", opt.log], ["/data/layout.json", opt.layout]]));
  const base = `http://127.0.0.1:${server.address().port}`;
  const userDir = await mkdtemp(join(tmpdir(), "deckpose-viewer-"));
  const { child, wsUrl } = await launch(chromium, userDir, opt.width, opt.height);
  const console_ = [];
  let report;
  let loaded = false;
  try {
    const ws = new WebSocket(wsUrl, { perMessageDeflate: false, maxPayload: 256 * 1024 * 1024 });
    await new Promise((ok, fail) => { ws.once("open", ok); ws.once("error", fail); });
    const cdp = new Cdp(ws);
    const { targetId } = await cdp.send("Target.createTarget", { url: "about:blank" });
    const { sessionId } = await cdp.send("Target.attachToTarget", { targetId, flatten: true });
    const page = (method, params) => cdp.send(method, params, sessionId);
    cdp.on((msg) => {
      if (msg.sessionId !== sessionId) return;
      if (msg.method === "Runtime.consoleAPICalled" && ["error", "warning", "assert"].includes(msg.params.type)) {
        console_.push(`${msg.params.type}: ${msg.params.args.map((a) => a.value ?? a.description ?? "").join(" ")}`.slice(0, 2000));
      } else if (msg.method === "Runtime.exceptionThrown") {
        console_.push(`exception: ${msg.params.exceptionDetails.exception?.description ?? msg.params.exceptionDetails.text}`.slice(0, 2000));
      }
    });
    await page("Runtime.enable");
    await page("Page.enable");
    await page("Emulation.setDeviceMetricsOverride", { width: opt.width, height: opt.height, deviceScaleFactor: 1, mobile: false });
    const url = new URL(`${base}/index.html`);
    url.searchParams.set("ds", "remote-file");
    url.searchParams.set("ds.url", `${base}/data/log.mcap`);
    url.searchParams.set("layoutId", "deckpose");
    url.searchParams.set("layout", `${base}/data/layout.json`);
    if (opt.time) url.searchParams.set("time", opt.time);
    await page("Page.navigate", { url: url.href });

    const evaluate = async (fn, ...args) => {
      const r = await page("Runtime.evaluate", { expression: `(${fn})(${args.map((a) => JSON.stringify(a)).join(",")})`,
        returnByValue: true, awaitPromise: true });
      if (r.exceptionDetails) throw new Error(r.exceptionDetails.exception?.description ?? r.exceptionDetails.text);
      return r.result.value;
    };
    // Wait for the player: the app shows the log's time range once the file is open.
    const deadline = Date.now() + opt.timeoutS * 1000;
    while (Date.now() < deadline) {
      const s = await evaluate(pageState).catch(() => undefined);
      if (s?.mounted && s.panels.length > 0 && !/\bLoading\b|Initializing/.test(s.text) && /log\.mcap/.test(s.text)) {
        loaded = true;
        break;
      }
      await sleep(500);
    }
    await sleep(opt.settleS * 1000);
    // The Problems tab, so that its list is read (and shown in the screenshot).
    const problems = await evaluate(readProblems);
    await sleep(300);
    const state = await evaluate(pageState);
    const shot = await page("Page.captureScreenshot", { format: "png" });
    await writeFile(join(opt.out, "screenshot.png"), Buffer.from(shot.data, "base64"));
    await writeFile(join(opt.out, "page.txt"), state.text);
    report = { loaded, url: url.href, viewport: [opt.width, opt.height], problems, ...state, console: console_ };
    await writeFile(join(opt.out, "report.json"), JSON.stringify(report, null, 1));
    ws.close();
  } finally {
    killGroup(child);
    server.close();
    await rm(userDir, { recursive: true, force: true }).catch(() => {});
  }
  console.log(`${loaded ? "loaded" : "NOT loaded"}: ${join(opt.out, "screenshot.png")}, ${join(opt.out, "report.json")}`);
  process.exit(loaded ? 0 : 1);
}

main().catch((err) => {
  console.error(`view.mjs: ${err.stack ?? err}`);
  process.exit(1);
});
