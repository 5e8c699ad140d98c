// bbzide's Buzz editor (our own code; no third-party editor).
//
// Design: a transparent <textarea> (which keeps native typing, selection, undo, IME and clipboard)
// lies exactly over a <pre> that shows the same text highlighted; a gutter on the left numbers
// the lines and carries the error markers. Both layers share one font and line height, and the
// textarea is sized to its content so that a single outer box scrolls both together.
//
// The text lives on the server (bbzide/ui/editor_server.py), which owns the .bzz file. The page
// talks to it over one websocket on the IDE's own port (/editor/socket; the browser sends the
// IDE's cookie with it), one JSON request -> one JSON reply, matched by id:
//   {op: "state"}   -> {code: 200, revision, filename, status, diagnostics_revision, diagnostics}
//   {op: "source"}  -> {code: 200, revision, text}
//   {op: "save", text, base_revision} -> state + saved_revision (the revision holding this text;
//                                        state.revision may already be newer), or
//                                        {code: 409, revision, text} when the file
//                                        changed since base_revision (another tab, another editor)
//   {op: "compile"} -> state
// A poll of "state" brings in external edits (the file watcher bumps the revision) and the
// diagnostics of the latest compile. A 409 never loses text: the user's stays in the editor and
// a notice offers the file's version or overwriting it with theirs.

"use strict";

const KEYWORDS = new Set(["var", "if", "else", "function", "return", "for", "while",
                          "and", "or", "not", "nil", "include"]);
// Globals every BittyBuzz robot has, plus the platform functions of the shipped worlds.
const BUILTINS = new Set(["id", "self", "stigmergy", "swarm", "neighbors", "foreach", "map",
  "filter", "reduce", "size", "log", "led", "set_led", "set_motors", "set_motor", "delay",
  "math", "string", "create", "broadcast", "listen", "ignore", "get", "put", "count",
  "kin", "nonkin", "join", "leave", "in", "select", "exec", "others", "onconflict",
  "onconflictlost", "init", "step", "destroy", "rand", "random", "goto", "pose", "position"]);

const EDIT_DEBOUNCE_MS = 400;   // "compile as you type": wait for a pause in typing
const POLL_MS = 250;            // external saves must show within ~0.5 s
const INDENT = "  ";

const source = document.getElementById("source");
const highlight = document.getElementById("highlight-code");
const highlightPre = document.getElementById("highlight");
const gutter = document.getElementById("gutter");
const diagnosticsBox = document.getElementById("diagnostics");
const statusBox = document.getElementById("status");
const filenameBox = document.getElementById("filename");

const conflictBox = document.getElementById("conflict");

let localRevision = -1;     // revision of the text the textarea shows (server numbering)
let editTimer = null;       // pending debounced upload
let uploading = false;
let uploadAgain = false;    // the text changed while an upload was out: send it when it returns
let conflict = null;        // {revision, text} of the file when a save was refused, until resolved
let lastState = null;

// ---- tokenizer --------------------------------------------------------------------------
// Follows the Buzz lexer closely enough for colouring: '#' comments to end of line, strings in
// either quote with backslash escapes (raw newlines allowed), numbers = digit then digits/dots.
function tokenize(text) {
  const tokens = [];
  let i = 0;
  const n = text.length;
  const push = (kind, start) => tokens.push({kind, start, end: i});
  while (i < n) {
    const start = i;
    const c = text[i];
    if (c === "#") {
      while (i < n && text[i] !== "\n") i++;
      push("comment", start);
    } else if (c === '"' || c === "'") {
      i++;
      while (i < n && text[i] !== c) { if (text[i] === "\\") i++; i++; }
      i = Math.min(n, i + 1);
      push("string", start);
    } else if (c >= "0" && c <= "9") {
      while (i < n && /[0-9.]/.test(text[i])) i++;
      push("number", start);
    } else if (/[A-Za-z]/.test(c)) {
      while (i < n && /[A-Za-z0-9_]/.test(text[i])) i++;
      const word = text.slice(start, i);
      push(KEYWORDS.has(word) ? "keyword" : BUILTINS.has(word) ? "builtin" : "name", start);
    } else if (c === "\n") {
      i++;
      push("newline", start);
    } else if (/[ \t\r]/.test(c)) {
      while (i < n && /[ \t\r]/.test(text[i])) i++;
      push("space", start);
    } else {
      i++;
      push(/[-+*/%^<>=!&|]/.test(c) ? "operator" : "punct", start);
    }
  }
  return tokens;
}

function escapeHtml(s) {
  return s.replace(/&/g, "&amp;").replace(/</g, "&lt;").replace(/>/g, "&gt;");
}

// Offsets of the first character of every line (line 1 at index 0).
function lineStarts(text) {
  const starts = [0];
  for (let i = 0; i < text.length; i++) if (text[i] === "\n") starts.push(i + 1);
  return starts;
}

// Where a diagnostic points: clamp unknown lines (e.g. the end-of-file token's line 0) to the last.
function diagnosticOffset(diag, starts, text) {
  let line = diag.line;
  if (!(line >= 1 && line <= starts.length)) line = starts.length;
  const lineStart = starts[line - 1];
  const lineEnd = line < starts.length ? starts[line] - 1 : text.length;
  return {line, offset: Math.min(lineStart + Math.max(0, diag.col || 0), lineEnd)};
}

function currentDiagnostics() {
  if (!lastState) return [];
  const compiled = lastState.diagnostics_revision === localRevision ? lastState.diagnostics || [] : [];
  // runtime errors of the robots: only on the text of the program they run
  const runtime = lastState.runtime_revision === localRevision ? lastState.runtime || [] : [];
  return [...runtime, ...compiled];
}

// How a diagnostic reads in the list and the gutter tooltip.
function diagnosticText(d) {
  if (d.severity !== "runtime") return `${d.severity} ${d.line}:${d.col}: ${d.message}`;
  const robots = d.robots === 1 ? "1 robot" : `${d.robots} robots`;
  return `runtime error ${d.line}:${d.col} (${robots} stopped here): ${d.message}`;
}

// ---- rendering -----------------------------------------------------------------------------
function render() {
  const text = source.value;
  const starts = lineStarts(text);
  const diags = currentDiagnostics();
  const errorOffsets = new Map();     // offset -> message (errors underline the token there)
  const markedLines = new Map();      // line -> messages
  const robotsOnLine = new Map();     // line -> robots stopped by a runtime error there
  for (const d of diags) {
    const where = diagnosticOffset(d, starts, text);
    if (d.severity !== "warning") errorOffsets.set(where.offset, d.message);
    if (d.severity === "runtime") {
      robotsOnLine.set(where.line, (robotsOnLine.get(where.line) || 0) + d.robots);
    }
    const list = markedLines.get(where.line) || [];
    list.push(diagnosticText(d));
    markedLines.set(where.line, list);
  }
  let html = "";
  const tokens = tokenize(text);
  const pending = new Set(errorOffsets.keys());
  for (const t of tokens) {
    let piece = escapeHtml(text.slice(t.start, t.end));
    let hit = null;
    for (const off of pending) if (off >= t.start && off < t.end) { hit = off; break; }
    if (hit !== null && t.kind !== "newline") {
      pending.delete(hit);
      html += `<span class="tok-${t.kind} error-span" title="${escapeHtml(errorOffsets.get(hit))}">${piece}</span>`;
      continue;
    }
    if (hit !== null) {  // error at end of line: show a visible marker before the newline
      pending.delete(hit);
      html += `<span class="error-span" title="${escapeHtml(errorOffsets.get(hit))}"> </span>`;
    }
    html += t.kind === "space" || t.kind === "newline" || t.kind === "name" || t.kind === "punct"
      ? piece : `<span class="tok-${t.kind}">${piece}</span>`;
  }
  for (const _ of pending) html += '<span class="error-span"> </span>';  // error at end of text
  if (text.endsWith("\n") || text === "") html += " ";
  highlight.innerHTML = html;

  let gutterHtml = "";
  for (let line = 1; line <= starts.length; line++) {
    const marks = markedLines.get(line);
    const robots = robotsOnLine.get(line);
    const kind = robots ? "runtime-line"
      : marks && marks.some((m) => m.startsWith("error")) ? "error-line" : "warning-line";
    const badge = robots ? `<span class="robot-count">${robots}</span>` : "";
    gutterHtml += marks
      ? `<div class="${kind}" data-line="${line}" title="${escapeHtml(marks.join("\n"))}">${badge}${line}</div>`
      : `<div>${line}</div>`;
  }
  gutter.innerHTML = gutterHtml;

  diagnosticsBox.innerHTML = diags.map((d) =>
    `<div class="diag-${d.severity}" data-line="${d.line}" data-col="${d.col}">` +
    `${escapeHtml(diagnosticText(d))}</div>`).join("");
  // Size the textarea to its content so the outer box scrolls both layers together.
  source.style.height = highlightPre.offsetHeight + "px";
  source.style.width = Math.max(highlightPre.offsetWidth, source.parentElement.clientWidth) + "px";
  renderStatus();
}

function renderStatus() {
  if (!lastState) return;
  filenameBox.textContent = lastState.filename;
  let kind = lastState.status;
  let label = {ok: "compiled", error: "error", busy: "compiling…", idle: "…"}[kind] || kind;
  if (editTimer !== null || uploading || lastState.diagnostics_revision !== localRevision) {
    kind = "busy"; label = "compiling…";
  }
  if (conflict !== null) { kind = "error"; label = "not saved: file changed"; }
  statusBox.className = "status-" + kind;
  statusBox.textContent = label;
  if (kind === "ok" && lastState.summary) statusBox.textContent = lastState.summary;
}

// ---- talking to the server ---------------------------------------------------------------
const RECONNECT_MS = 1000;  // retry a lost connection once a second (the IDE may be restarting)
let socket = null;
let socketReady = null;     // promise of an open socket
let nextId = 1;
const waiting = new Map();  // id -> {resolve, reject}

function connect() {
  const url = new URL("socket", window.location.href);
  url.protocol = url.protocol === "https:" ? "wss:" : "ws:";
  url.search = "";
  socketReady = new Promise((resolve, reject) => {
    socket = new WebSocket(url);
    socket.onopen = () => resolve(socket);
    socket.onmessage = (event) => {
      const reply = JSON.parse(event.data);
      const request = waiting.get(reply.id);
      if (!request) return;
      waiting.delete(reply.id);
      request.resolve(reply);
    };
    socket.onclose = () => {
      for (const request of waiting.values()) request.reject(new Error("connection lost"));
      waiting.clear();
      reject(new Error("connection lost"));
      statusBox.className = "status-error";
      statusBox.textContent = "server gone";
      setTimeout(connect, RECONNECT_MS);
    };
  });
  socketReady.catch(() => {});
}

async function call(op, fields = {}) {
  const open = await socketReady;
  const id = nextId++;
  const reply = new Promise((resolve, reject) => waiting.set(id, {resolve, reject}));
  open.send(JSON.stringify({id, op, ...fields}));
  return reply;
}

async function loadSource() {
  const data = await call("source");
  // The user typed while the request was out: their text wins, it is being uploaded.
  if (hasLocalEdits() || data.revision < localRevision) return;
  showText(data.text, data.revision);
}

function showText(text, revision) {
  const {selectionStart, selectionEnd} = source;
  source.value = text;
  localRevision = revision;
  source.selectionStart = Math.min(selectionStart, text.length);
  source.selectionEnd = Math.min(selectionEnd, text.length);
  render();
}

function hasLocalEdits() {
  return editTimer !== null || uploading || conflict !== null;
}

async function uploadNow(baseRevision = localRevision) {
  if (editTimer !== null) { clearTimeout(editTimer); editTimer = null; }
  if (uploading) { uploadAgain = true; return; }  // one save at a time, in order
  uploading = true;
  try {
    const reply = await call("save", {text: source.value, base_revision: baseRevision});
    if (reply.code === 409) {
      showConflict(reply);
    } else if (reply.code === 200) {
      localRevision = reply.saved_revision;  // a newer revision, if any, comes with the next poll
      applyState(reply);
    } else {
      statusBox.className = "status-error";
      statusBox.textContent = reply.error || `save refused (${reply.code})`;
    }
  } finally {
    uploading = false;
  }
  if (uploadAgain && conflict === null) { uploadAgain = false; uploadNow(); }
}

async function compileNow() {
  if (conflict !== null) return;  // the notice asks first which text to keep
  if (editTimer !== null || uploading) { await uploadNow(); return; }
  applyState(await call("compile"));
}

function applyState(state) {
  lastState = state;
  render();
}

let polling = false;
async function poll() {
  if (polling) return;       // a slow answer (a compile) must not pile up polls behind it
  polling = true;
  try {
    const state = await call("state");
    // Revisions only grow: an answer older than our last upload is stale, not an external edit.
    if (state.revision > localRevision && !hasLocalEdits()) {
      lastState = state;
      await loadSource();          // an external save (or another tab) changed the text
    } else {
      applyState(state);
    }
  } catch (error) {
    // connection lost: onclose shows it and reconnects
  } finally {
    polling = false;
  }
}

// ---- a save refused because the file changed -----------------------------------------------
function showConflict(reply) {
  conflict = {revision: reply.revision, text: reply.text};
  uploadAgain = false;
  lastState = reply;
  conflictBox.hidden = false;
  render();
}

function takeDiskVersion() {
  const disk = conflict;
  conflict = null;
  conflictBox.hidden = true;
  showText(disk.text, disk.revision);
  poll();
}

function overwriteWithMine() {
  const base = conflict.revision;
  conflict = null;
  conflictBox.hidden = true;
  uploadNow(base);
}

// ---- editing -------------------------------------------------------------------------------
function scheduleUpload() {
  if (conflict !== null) return;  // kept in the editor until the user chooses in the notice
  if (editTimer !== null) clearTimeout(editTimer);
  editTimer = setTimeout(() => { editTimer = null; uploadNow(); }, EDIT_DEBOUNCE_MS);
}

function insertText(text) {
  // execCommand keeps the browser's undo history; fall back to setRangeText where it is missing.
  if (!document.execCommand("insertText", false, text)) {
    source.setRangeText(text, source.selectionStart, source.selectionEnd, "end");
    source.dispatchEvent(new Event("input"));
  }
}

// Shift-Tab: remove up to one indentation level from the start of the caret's line.
function dedentCurrentLine() {
  const text = source.value;
  const lineStart = text.lastIndexOf("\n", source.selectionStart - 1) + 1;
  const leading = text.slice(lineStart).match(/^ {1,2}|^\t/);
  if (!leading) return;
  const caret = source.selectionStart;
  source.setSelectionRange(lineStart, lineStart + leading[0].length);
  insertText("");
  const back = Math.max(lineStart, caret - leading[0].length);
  source.setSelectionRange(back, back);
}

source.addEventListener("input", () => { render(); scheduleUpload(); });
source.addEventListener("keydown", (event) => {
  if ((event.ctrlKey || event.metaKey) && (event.key === "s" || event.key === "Enter")) {
    event.preventDefault();
    compileNow();
  } else if (event.key === "Tab" && event.shiftKey) {
    event.preventDefault();
    dedentCurrentLine();
  } else if (event.key === "Tab" && !event.ctrlKey && !event.altKey) {
    event.preventDefault();
    insertText(INDENT);
  } else if (event.key === "Enter" && !event.shiftKey && !event.ctrlKey) {
    // Keep the indentation of the current line, one level more after an opening brace.
    const before = source.value.slice(0, source.selectionStart);
    const line = before.slice(before.lastIndexOf("\n") + 1);
    let indent = line.match(/^[ \t]*/)[0];
    if (/[{(\[]\s*$/.test(line)) indent += INDENT;
    event.preventDefault();
    insertText("\n" + indent);
  }
});
diagnosticsBox.addEventListener("click", (event) => {
  const row = event.target.closest("[data-line]");
  if (!row) return;
  const starts = lineStarts(source.value);
  const where = diagnosticOffset({line: +row.dataset.line, col: +row.dataset.col}, starts, source.value);
  source.focus();
  source.setSelectionRange(where.offset, where.offset);
});
document.getElementById("compile").addEventListener("click", compileNow);
document.getElementById("take-disk").addEventListener("click", takeDiskVersion);
document.getElementById("overwrite").addEventListener("click", overwriteWithMine);
window.addEventListener("resize", render);

// The first poll finds revision >= 0 > localRevision and loads the text; polls go on through
// lost connections (call() waits for the reconnected socket).
connect();
poll();
setInterval(poll, POLL_MS);
