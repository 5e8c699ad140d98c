// bbzide's Buzz editor page: CodeMirror 6 with our Buzz mode (buzz-language.js), completion and
// hover docs (completion.js) and diagnostics (diagnostics.js), bundled by editor/build.mjs.
//
// The text lives on the server (bbzide/ui/editor_server.py), which owns the .bzz file. The page
// talks to it over one websocket on the IDE's own port (/editor/socket; the browser sends the
// IDE's cookie with it), one JSON request -> one JSON reply, matched by id:
//   {op: "state"}   -> {code: 200, revision, filename, status, world, diagnostics_revision,
//                       diagnostics, runtime_revision, runtime}
//   {op: "source"}  -> {code: 200, revision, text}
//   {op: "save", text, base_revision} -> state + saved_revision (the revision holding this text;
//                                        state.revision may already be newer), or
//                                        {code: 409, revision, text} when the file
//                                        changed since base_revision (another tab, another editor)
//   {op: "compile"} -> state
//   {op: "reference"} -> {world, items}: the built-ins and the world's host functions
//   {op: "breakpoints", revision, breakpoints} -> state; every state carries the breakpoints in
//                       force (breakpoints, breakpoints_revision, breakpoints_generation) and
//                       where the debugger paused (paused: {line, robot, reason, revision} | null)
// A poll of "state" brings in external edits (the file watcher bumps the revision) and the
// diagnostics of the latest compile. A 409 never loses text: the user's stays in the editor and
// a notice offers the file's version or overwriting it with theirs.
//
// Undo history: a compile changes no text, and a text from the server replaces only the part
// that differs (one undoable change), so Ctrl-Z goes on working across both.

import { autocompletion, completionKeymap } from "@codemirror/autocomplete";
import { defaultKeymap, history, historyKeymap, indentWithTab } from "@codemirror/commands";
import { bracketMatching, indentOnInput, indentUnit, syntaxHighlighting } from "@codemirror/language";
import { highlightSelectionMatches, search, searchKeymap } from "@codemirror/search";
import { Annotation, Compartment, EditorState, Prec } from "@codemirror/state";
import {
  EditorView, drawSelection, highlightActiveLine, highlightActiveLineGutter, highlightSpecialChars,
  hoverTooltip, keymap, lineNumbers,
} from "@codemirror/view";

import { buzzHighlighter, buzzIndentation, buzzLanguage } from "./buzz-language.js";
import { breakpointList, breakpointsExtension, setBreakpoints, showPaused } from "./breakpoints.js";
import { builtinNames, buzzCompletions, hoverDoc, setReferenceItems } from "./completion.js";
import { diagnosticPlace, diagnosticText, diagnosticsExtension, showDiagnostics } from "./diagnostics.js";

const EDIT_DEBOUNCE_MS = 400;   // "compile as you type": wait for a pause in typing
const POLL_MS = 250;            // external saves must show within ~0.5 s
const RECONNECT_MS = 1000;      // retry a lost connection once a second (the IDE may be restarting)
const HOVER_DELAY_MS = 300;     // long enough not to flash docs while the mouse crosses the text
const INDENT = "  ";

const diagnosticsBox = document.getElementById("diagnostics");
const statusBox = document.getElementById("status");
const filenameBox = document.getElementById("filename");
const conflictBox = document.getElementById("conflict");

let localRevision = -1;     // revision of the text the editor shows (server numbering)
let editTimer = null;       // pending debounced upload
let uploading = false;
let uploadAgain = false;    // the text changed while an upload was out: send it when it returns
let conflict = null;        // {revision, text} of the file when a save was refused, until resolved
let lastState = null;
let shownDiagnostics = "";  // what the editor shows now (JSON), to dispatch only on a change
let referenceWorld = null;  // the world whose built-ins completion offers
let breakpointsOut = 0;     // breakpoint lists sent and not yet answered
let breakpointsGeneration = -1;  // the newest breakpoint list the server told us of
let shownPaused = "null";   // where the debugger paused, as shown (JSON)

/** Marks a transaction that brings the server's text: it is not uploaded back. */
const fromServer = Annotation.define();
const languageSlot = new Compartment();

const view = new EditorView({
  parent: document.getElementById("editor"),
  state: EditorState.create({
    doc: "",
    extensions: [
      breakpointsExtension(() => sendBreakpoints()),  // left of the line numbers, as IDEs do
      lineNumbers(),
      highlightActiveLineGutter(),
      highlightSpecialChars(),
      history(),
      drawSelection(),
      indentUnit.of(INDENT),
      buzzIndentation,
      indentOnInput(),
      languageSlot.of(buzzLanguage(new Set())),
      syntaxHighlighting(buzzHighlighter),
      bracketMatching(),
      highlightActiveLine(),
      highlightSelectionMatches(),
      search({ top: true }),
      autocompletion({ override: [buzzCompletions], icons: true }),
      hoverTooltip((v, pos) => {
        const doc = hoverDoc(v.state, pos);
        if (!doc) return null;
        return { pos: doc.from, end: doc.to, above: true, create: () => ({ dom: doc.node }) };
      }, { hoverTime: HOVER_DELAY_MS }),
      diagnosticsExtension(),
      Prec.highest(keymap.of([
        { key: "Mod-s", run: () => { compileNow(); return true; } },
        { key: "Mod-Enter", run: () => { compileNow(); return true; } },
      ])),
      keymap.of([...completionKeymap, ...searchKeymap, ...historyKeymap, ...defaultKeymap,
        indentWithTab]),
      EditorView.contentAttributes.of({ id: "source", "aria-label": "Buzz source",
        spellcheck: "false", autocapitalize: "off", autocorrect: "off" }),
      EditorView.updateListener.of((update) => {
        if (!update.docChanged) return;
        if (update.transactions.some((t) => t.annotation(fromServer))) return;
        scheduleUpload();
        renderStatus();
      }),
    ],
  }),
});

// For tests and the console: the text shown, and the view itself.
window.buzzEditor = {
  view, text: () => view.state.doc.toString(), breakpoints: () => breakpointList(view.state),
};

// ---- diagnostics ---------------------------------------------------------------------------
function currentDiagnostics() {
  if (!lastState) return [];
  const compiled = lastState.diagnostics_revision === localRevision ? lastState.diagnostics || [] : [];
  // runtime errors of the robots: only on the text of the program they run
  const runtime = lastState.runtime_revision === localRevision ? lastState.runtime || [] : [];
  return [...runtime, ...compiled];
}

function render() {
  // While the user's text waits for its upload the markers stay where they are (they follow the
  // text): the server's line numbers belong to the text it has.
  if (!hasLocalEdits()) {
    const diags = currentDiagnostics();
    const key = JSON.stringify(diags);
    if (key !== shownDiagnostics) {
      shownDiagnostics = key;
      view.dispatch(showDiagnostics(view.state, diags));
      diagnosticsBox.replaceChildren(...diags.map((d) => {
        const row = document.createElement("div");
        row.className = `diag-${d.severity}`;
        row.dataset.line = String(d.line);
        row.dataset.col = String(d.col);
        row.textContent = diagnosticText(d);
        return row;
      }));
    }
  }
  renderDebugger();
  renderStatus();
}

/** The server's breakpoints (when they belong to this text and are newer than our last change)
 *  and the paused line (when the robots run this text). */
function renderDebugger() {
  if (hasLocalEdits() || !lastState) return;
  const s = lastState;
  if (breakpointsOut === 0 && s.breakpoints_revision === localRevision
      && s.breakpoints_generation >= breakpointsGeneration
      && JSON.stringify(s.breakpoints) !== JSON.stringify(breakpointList(view.state))) {
    breakpointsGeneration = s.breakpoints_generation;
    view.dispatch(setBreakpoints(view.state, s.breakpoints));
  }
  const paused = s.paused && s.paused.revision === localRevision ? s.paused : null;
  const key = JSON.stringify(paused);
  if (key !== shownPaused) {
    shownPaused = key;
    const spec = showPaused(view.state, paused);
    if (paused && paused.line >= 1 && paused.line <= view.state.doc.lines) {
      spec.effects = [spec.effects, EditorView.scrollIntoView(view.state.doc.line(paused.line).from, { y: "center" })];
    }
    view.dispatch(spec);
  }
}

/** Send the breakpoints shown (their lines belong to the text the server has: while an edit
 *  waits for its upload, the upload sends them). */
async function sendBreakpoints() {
  if (hasLocalEdits()) return;
  breakpointsOut++;
  try {
    const reply = await call("breakpoints", { revision: localRevision, breakpoints: breakpointList(view.state) });
    if (reply.code === 200) breakpointsGeneration = Math.max(breakpointsGeneration, reply.breakpoints_generation);
    breakpointsOut--;
    if (reply.code === 200) applyState(reply);
  } catch (error) {
    breakpointsOut--;  // connection lost: the next change or save sends them again
  }
}

function renderStatus() {
  if (!lastState) return;
  filenameBox.textContent = lastState.filename;
  let kind = lastState.status;
  let label = { ok: "compiled", error: "error", busy: "compiling…", idle: "…" }[kind] || kind;
  if (editTimer !== null || uploading || lastState.diagnostics_revision !== localRevision) {
    kind = "busy"; label = "compiling…";
  }
  if (conflict !== null) { kind = "error"; label = "not saved: file changed"; }
  statusBox.className = "status-" + kind;
  statusBox.textContent = label;
  if (kind === "ok" && lastState.summary) statusBox.textContent = lastState.summary;
}

// ---- talking to the server ---------------------------------------------------------------
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
  const reply = new Promise((resolve, reject) => waiting.set(id, { resolve, reject }));
  open.send(JSON.stringify({ id, op, ...fields }));
  return reply;
}

async function loadSource() {
  const data = await call("source");
  // The user typed while the request was out: their text wins, it is being uploaded.
  if (hasLocalEdits() || data.revision < localRevision) return;
  showText(data.text, data.revision);
}

/** Show the server's `text`: only the part that differs changes (one undoable step). */
function showText(text, revision) {
  const current = view.state.doc.toString();
  const firstText = localRevision < 0;
  localRevision = revision;
  if (text !== current) {
    let start = 0;
    while (start < text.length && start < current.length && text[start] === current[start]) start++;
    let endText = text.length;
    let endCurrent = current.length;
    while (endText > start && endCurrent > start && text[endText - 1] === current[endCurrent - 1]) {
      endText--; endCurrent--;
    }
    view.dispatch({
      changes: { from: start, to: endCurrent, insert: text.slice(start, endText) },
      annotations: fromServer.of(true),
    });
  }
  shownDiagnostics = "";  // markers are placed again on this text
  shownPaused = "";
  render();
  // The breakpoints shown moved with the text: they belong to `revision` now. (A page that
  // just opened shows none yet: it takes the server's, and must not send its empty list.)
  if (!firstText && breakpointList(view.state).length > 0) sendBreakpoints();
}

function hasLocalEdits() {
  return editTimer !== null || uploading || conflict !== null;
}

async function uploadNow(baseRevision = localRevision) {
  if (editTimer !== null) { clearTimeout(editTimer); editTimer = null; }
  if (uploading) { uploadAgain = true; return; }  // one save at a time, in order
  uploading = true;
  try {
    const reply = await call("save", { text: view.state.doc.toString(), base_revision: baseRevision });
    if (reply.code === 409) {
      showConflict(reply);
    } else if (reply.code === 200) {
      localRevision = reply.saved_revision;  // a newer revision, if any, comes with the next poll
      uploading = false;
      shownDiagnostics = "";
      shownPaused = "";
      applyState(reply);
      if (!hasLocalEdits()) sendBreakpoints();  // their lines now belong to the saved text
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
  shownDiagnostics = "";
  applyState(await call("compile"));
}

function applyState(state) {
  lastState = state;
  if (state.world !== undefined && state.world !== referenceWorld) loadReference(state.world);
  render();
}

/** The built-ins and host functions of `world`, for completion, hover and colours. */
async function loadReference(world) {
  referenceWorld = world;
  const reply = await call("reference");
  if (reply.code !== 200) return;
  setReferenceItems(reply.items);
  view.dispatch({ effects: languageSlot.reconfigure(buzzLanguage(builtinNames(reply.items))) });
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
      applyState(state);
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
  conflict = { revision: reply.revision, text: reply.text };
  uploadAgain = false;
  lastState = reply;
  conflictBox.hidden = false;
  renderStatus();
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

diagnosticsBox.addEventListener("click", (event) => {
  const row = event.target.closest("[data-line]");
  if (!row) return;
  const place = diagnosticPlace({ line: +row.dataset.line, col: +row.dataset.col }, view.state.doc);
  view.dispatch({ selection: { anchor: place.offset }, scrollIntoView: true });
  view.focus();
});
document.getElementById("compile").addEventListener("click", compileNow);
document.getElementById("take-disk").addEventListener("click", takeDiskVersion);
document.getElementById("overwrite").addEventListener("click", overwriteWithMine);

// The first poll finds revision >= 0 > localRevision and loads the text; polls go on through
// lost connections (call() waits for the reconnected socket).
connect();
poll();
setInterval(poll, POLL_MS);
