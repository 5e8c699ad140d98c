// Completion and hover docs for Buzz: the built-ins and the current world's host functions (from
// the server, which reads bbzide/compiler/reference.py and bbzide/worlds/reference.py: the same
// tables as the reference page), plus the script's own globals and locals.
//
// Design: the script's names come from a scan of its tokens (lexBuzz), not from the compiler,
// so they are there while the text does not compile yet. Buzz scoping, simplified: `var x`
// inside a function and a function's parameters are locals of that function; `var x`, `x = ...`
// and `function f` at the top level are globals. Locals are offered only inside their function,
// after the cursor has passed their declaration.

import { KEYWORDS, lexBuzz } from "./buzz-language.js";

/** The reference items the server sent: [{label, name, signature, doc, memory, group}]. */
let referenceItems = [];
let itemsByName = new Map();

export function setReferenceItems(items) {
  referenceItems = items;
  itemsByName = new Map(items.map((item) => [item.name, item]));
}

/** Names to colour as built-ins: every item's first part (`neighbors`, `led`, `id`). */
export function builtinNames(items) {
  return new Set(items.map((item) => item.name.split(".")[0]));
}

/**
 * The script's declared names: {globals: Map name -> {kind, line, signature}, scopes: [{from, to,
 * locals: Map}]} where each scope is a function body (offsets of its braces).
 */
export function scanScript(text) {
  const tokens = lexBuzz(text).filter((t) => t.kind !== "comment");
  const globals = new Map();
  const scopes = [];
  const open = [];            // braces still open: {scope or null, from}
  let pendingParams = null;   // a function's parameters, waiting for its body's brace
  const lineOf = (offset) => text.slice(0, offset).split("\n").length;
  const innermost = () => {
    for (let k = open.length - 1; k >= 0; k--) if (open[k].scope) return open[k].scope;
    return null;
  };
  for (let i = 0; i < tokens.length; i++) {
    const t = tokens[i];
    const next = tokens[i + 1];
    const previous = tokens[i - 1];
    if (t.kind === "keyword" && t.text === "function") {
      let j = i + 1;
      let name = null;
      if (tokens[j] && tokens[j].kind === "name") { name = tokens[j]; j++; }
      const params = [];
      if (tokens[j] && tokens[j].text === "(") {
        for (j++; j < tokens.length && tokens[j].text !== ")"; j++) {
          if (tokens[j].kind === "name") params.push(tokens[j]);
        }
      }
      const signature = `${name ? name.text : "function"}(${params.map((p) => p.text).join(", ")})`;
      if (name) {
        const target = innermost() ? innermost().locals : globals;
        if (!target.has(name.text)) {
          target.set(name.text, { kind: "function", line: lineOf(name.from), signature, at: name.from });
        }
      }
      pendingParams = params.map((p) => [p.text, { kind: "parameter", line: lineOf(p.from), at: p.from }]);
    } else if (t.text === "{") {
      const scope = pendingParams ? { from: t.from, to: text.length, locals: new Map(pendingParams) } : null;
      if (scope) scopes.push(scope);
      open.push({ scope });
      pendingParams = null;
    } else if (t.text === "}") {
      const closed = open.pop();
      if (closed && closed.scope) closed.scope.to = t.to;
    } else if (t.kind === "keyword" && t.text === "var" && next && next.kind === "name") {
      const scope = innermost();
      const target = scope ? scope.locals : globals;
      if (!target.has(next.text)) {
        target.set(next.text, { kind: "variable", line: lineOf(next.from), at: next.from });
      }
    } else if (t.kind === "name" && next && next.text === "=" && (!previous || previous.text !== ".")) {
      const scope = innermost();
      const declaredLocally = open.some((o) => o.scope && o.scope.locals.has(t.text));
      if (!declaredLocally && !globals.has(t.text) && !scope) {
        globals.set(t.text, { kind: "variable", line: lineOf(t.from), at: t.from });
      }
    }
  }
  return { globals, scopes };
}

/** The locals visible at `offset`: those of every function body around it, declared before it. */
function localsAt(scan, offset) {
  const visible = new Map();
  for (const scope of scan.scopes) {
    if (scope.from < offset && offset < scope.to) {
      for (const [name, info] of scope.locals) if (info.at < offset) visible.set(name, info);
    }
  }
  return visible;
}

/** The reference item's doc as a DOM node: signature, text (`code` spans), memory cost. */
export function docNode(item) {
  const box = document.createElement("div");
  box.className = "bbz-doc";
  const signature = document.createElement("code");
  signature.className = "bbz-doc-signature";
  signature.textContent = item.signature;
  box.appendChild(signature);
  if (item.group) {
    const group = document.createElement("span");
    group.className = "bbz-doc-group";
    group.textContent = item.group;
    box.appendChild(group);
  }
  const text = document.createElement("div");
  text.className = "bbz-doc-text";
  appendWithCode(text, item.doc);
  box.appendChild(text);
  if (item.memory) {
    const memory = document.createElement("div");
    memory.className = "bbz-doc-memory";
    appendWithCode(memory, "Memory: " + item.memory + ".");
    box.appendChild(memory);
  }
  return box;
}

// `x` spans of the reference text as <code>, the rest as text (never parsed as HTML).
function appendWithCode(parent, text) {
  text.split("`").forEach((piece, index) => {
    if (index % 2 === 1) {
      const code = document.createElement("code");
      code.textContent = piece;
      parent.appendChild(code);
    } else if (piece) {
      parent.appendChild(document.createTextNode(piece));
    }
  });
}

function scriptDoc(name, info, scope) {
  return {
    name,
    signature: info.kind === "function" ? `function ${info.signature}` : name,
    doc: `${scope} ${info.kind} of this script, line ${info.line}.`,
    memory: "",
    group: "",
  };
}

const ITEM_TYPES = { "Host functions": "function" };

/** The completion source: `neighbors.` lists its members; a plain word lists every name. */
export function buzzCompletions(context) {
  const before = context.matchBefore(/(?:[A-Za-z_][A-Za-z0-9_]*\.)*[A-Za-z_0-9]*$/);
  if (!before) return null;
  const line = context.state.doc.lineAt(context.pos);
  const lineBefore = line.text.slice(0, context.pos - line.from);
  if (inCommentOrString(lineBefore)) return null;
  const typed = before.text;
  const dot = typed.lastIndexOf(".");
  const prefix = dot >= 0 ? typed.slice(0, dot) : "";
  const word = typed.slice(dot + 1);
  if (!context.explicit && word === "" && dot < 0) return null;
  const from = before.from + dot + 1;
  const options = [];
  if (prefix) {
    for (const item of referenceItems) {
      if (item.name.startsWith(prefix + ".") && !item.name.slice(prefix.length + 1).includes(".")) {
        options.push(referenceOption(item, item.name.slice(prefix.length + 1), "method"));
      }
    }
    return options.length ? { from, options, validFor: /^[A-Za-z0-9_]*$/ } : null;
  }
  const seen = new Set();
  const add = (option) => { if (!seen.has(option.label)) { seen.add(option.label); options.push(option); } };
  const scan = scanScript(context.state.doc.toString());
  for (const [name, info] of localsAt(scan, context.pos)) {
    add(scriptOption(name, info, "local", 3));
  }
  for (const [name, info] of scan.globals) add(scriptOption(name, info, "global", 2));
  for (const item of referenceItems) {
    if (!item.name.includes(".")) add(referenceOption(item, item.name, ITEM_TYPES[item.group] || "function"));
  }
  for (const item of referenceItems) {
    const head = item.name.split(".")[0];
    if (item.name.includes(".")) add({ label: head, type: "namespace", detail: item.group, boost: 1 });
  }
  for (const keyword of KEYWORDS) add({ label: keyword, type: "keyword", boost: -1 });
  return { from, options, validFor: /^[A-Za-z0-9_]*$/ };
}

function referenceOption(item, label, type) {
  const isValue = !item.signature || item.signature === item.name;
  return {
    label,
    type: isValue ? "variable" : type,
    detail: item.signature !== item.name ? item.signature : item.group,
    info: () => docNode(item),
    boost: 1,
  };
}

function scriptOption(name, info, scope, boost) {
  return {
    label: name,
    type: info.kind === "function" ? "function" : "variable",
    detail: `${scope}, line ${info.line}`,
    info: () => docNode(scriptDoc(name, info, scope)),
    boost,
  };
}

// Whether the end of `lineBefore` is inside a '#' comment or an open string (one line's view).
function inCommentOrString(lineBefore) {
  let quote = null;
  for (let i = 0; i < lineBefore.length; i++) {
    const c = lineBefore[i];
    if (quote) {
      if (c === "\\") i++;
      else if (c === quote) quote = null;
    } else if (c === "#") {
      return true;
    } else if (c === '"' || c === "'") {
      quote = c;
    }
  }
  return quote !== null;
}

/** The dotted name under `pos` (up to the end of the part under it), or null. */
export function nameAt(doc, pos) {
  const line = doc.lineAt(pos);
  const text = line.text;
  let start = pos - line.from;
  let end = start;
  while (start > 0 && /[A-Za-z0-9_.]/.test(text[start - 1])) start--;
  while (end < text.length && /[A-Za-z0-9_]/.test(text[end])) end++;
  if (start === end || inCommentOrString(text.slice(0, start))) return null;
  const name = text.slice(start, end).replace(/^\.+/, "");
  if (!/^[A-Za-z_]/.test(name)) return null;
  return { name, from: line.from + start + (text.slice(start, end).length - name.length), to: line.from + end };
}

/** The hover doc of the name at `pos`: a reference item, or one of the script's own names. */
export function hoverDoc(state, pos) {
  const found = nameAt(state.doc, pos);
  if (!found) return null;
  const item = itemsByName.get(found.name);
  if (item) return { ...found, node: docNode(item) };
  if (found.name.includes(".")) return null;
  const scan = scanScript(state.doc.toString());
  const local = localsAt(scan, pos).get(found.name);
  if (local) return { ...found, node: docNode(scriptDoc(found.name, local, "local")) };
  const global = scan.globals.get(found.name);
  if (global) return { ...found, node: docNode(scriptDoc(found.name, global, "global")) };
  return null;
}
