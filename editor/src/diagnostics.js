// The compiler's, the pitfall checker's and the running robots' diagnostics in the editor:
// underlines and hover messages through @codemirror/lint, and a marker gutter of our own (one
// mark per line: ● error, ▲ warning, and for a runtime error the number of robots stopped there).
//
// Design: the server numbers lines from 1 and columns from 0 (SourceLocation); `placeDiagnostics`
// turns them into offsets of the text shown (a line past the end, e.g. the end-of-file token's
// line 0, goes to the last line), and the underline covers the name or number there. The gutter
// markers live in a StateField, so they follow the text while the user types until the next
// compile replaces them.

import { setDiagnostics } from "@codemirror/lint";
import { RangeSet, StateEffect, StateField } from "@codemirror/state";
import { Decoration, EditorView, GutterMarker, gutter } from "@codemirror/view";

/** How a diagnostic reads in the list, the gutter's tooltip and the underline's. */
export function diagnosticText(d) {
  if (d.severity !== "runtime") return `${d.severity} ${d.line}:${d.col}: ${d.message}`;
  const robots = d.robots === 1 ? "1 robot" : `${d.robots} robots`;
  return `runtime error ${d.line}:${d.col} (${robots} stopped here): ${d.message}`;
}

/** The line (1-based, clamped to the text) and offset a diagnostic points at in `doc`. */
export function diagnosticPlace(d, doc) {
  const lineNumber = d.line >= 1 && d.line <= doc.lines ? d.line : doc.lines;
  const line = doc.line(lineNumber);
  return { line: lineNumber, offset: Math.min(line.from + Math.max(0, d.col || 0), line.to) };
}

// The end of the name or number starting at `offset`, else one character, else the offset.
function spanEnd(doc, offset) {
  const line = doc.lineAt(offset);
  const rest = line.text.slice(offset - line.from);
  const word = rest.match(/^[A-Za-z0-9_.]+/);
  if (word) return offset + word[0].length;
  return rest.length > 0 ? offset + 1 : offset;
}

class LineMarker extends GutterMarker {
  constructor(kind, lineNumber, title, robots) {
    super();
    this.kind = kind;
    this.lineNumber = lineNumber;
    this.title = title;
    this.robots = robots;
  }

  eq(other) {
    return other.kind === this.kind && other.title === this.title && other.robots === this.robots
      && other.lineNumber === this.lineNumber;
  }

  toDOM() {
    const mark = document.createElement("div");
    mark.className = this.kind;
    mark.dataset.line = String(this.lineNumber);
    mark.title = this.title;
    if (this.robots) {
      const badge = document.createElement("span");
      badge.className = "robot-count";
      badge.textContent = String(this.robots);
      mark.appendChild(badge);
    } else {
      mark.textContent = this.kind === "error-line" ? "●" : "▲";
    }
    return mark;
  }
}

const setLineMarks = StateEffect.define();

/** {markers: RangeSet of LineMarker, lines: DecorationSet of line backgrounds}, mapped on edits. */
const lineMarks = StateField.define({
  create: () => ({ markers: RangeSet.empty, lines: Decoration.none }),
  update(value, transaction) {
    for (const effect of transaction.effects) if (effect.is(setLineMarks)) return effect.value;
    if (!transaction.docChanged) return value;
    return { markers: value.markers.map(transaction.changes), lines: value.lines.map(transaction.changes) };
  },
  provide: (field) => EditorView.decorations.from(field, (value) => value.lines),
});

/** The editor extensions that show diagnostics (the lint state installs itself on first use). */
export function diagnosticsExtension() {
  return [
    lineMarks,
    gutter({
      class: "bbz-markers",
      markers: (view) => view.state.field(lineMarks).markers,
    }),
  ];
}

const SEVERITY = { error: "error", warning: "warning", runtime: "error" };

/** The transaction spec that shows `diagnostics` (server JSON) on the editor's current text. */
export function showDiagnostics(state, diagnostics) {
  const doc = state.doc;
  const lintDiagnostics = [];
  const perLine = new Map();  // line -> {kinds, titles, robots}
  for (const d of diagnostics) {
    const place = diagnosticPlace(d, doc);
    if (d.severity !== "warning" || d.line > 1 || d.col > 0) {
      lintDiagnostics.push({
        from: place.offset,
        to: spanEnd(doc, place.offset),
        severity: SEVERITY[d.severity] || "error",
        message: diagnosticText(d),
        markClass: d.severity === "warning" ? "warning-span" : `error-span ${d.severity}-span`,
        source: d.severity === "runtime" ? "robots" : "compiler",
      });
    }
    const entry = perLine.get(place.line) || { severities: new Set(), titles: [], robots: 0 };
    entry.severities.add(d.severity);
    entry.titles.push(diagnosticText(d));
    if (d.severity === "runtime") entry.robots += d.robots;
    perLine.set(place.line, entry);
  }
  const markers = [];
  const lines = [];
  for (const [lineNumber, entry] of [...perLine].sort((a, b) => a[0] - b[0])) {
    const kind = entry.robots ? "runtime-line"
      : entry.severities.has("error") ? "error-line" : "warning-line";
    const from = doc.line(lineNumber).from;
    markers.push(new LineMarker(kind, lineNumber, entry.titles.join("\n"), entry.robots).range(from));
    lines.push(Decoration.line({ class: `${kind}-bg` }).range(from));
  }
  const lint = setDiagnostics(state, lintDiagnostics);
  return {
    ...lint,
    effects: [
      ...[].concat(lint.effects || []),
      setLineMarks.of({ markers: RangeSet.of(markers), lines: Decoration.set(lines) }),
    ],
  };
}
