// Breakpoints and the debugger's current line in the editor.
//
// Design: a breakpoint is a red dot in a gutter of its own (left of the line numbers). A click
// on that gutter toggles the line's breakpoint; a right-click opens a small form for its
// options (a Buzz condition, one robot's id, a hit count). The dots live in a StateField as a
// RangeSet at line starts, so they follow the text while the user types; editor.js sends the
// whole list to the server after every change and every save (the server keeps the ones on
// lines with code and hands that list back, which replaces ours). The line where the debugger
// paused gets a yellow band and an arrow in the same gutter, only while the editor shows the
// text of the program the robots run (other text would put it on the wrong line).

import { RangeSet, StateEffect, StateField } from "@codemirror/state";
import { Decoration, EditorView, GutterMarker, gutter } from "@codemirror/view";

class BreakpointMarker extends GutterMarker {
  constructor(options) {
    super();
    this.options = options;  // {condition, robot, hit_count}
  }

  eq(other) {
    return JSON.stringify(other.options) === JSON.stringify(this.options);
  }

  toDOM() {
    const dot = document.createElement("div");
    const { condition, robot, hit_count: hits } = this.options;
    const extra = condition || robot !== null || hits;
    dot.className = extra ? "breakpoint breakpoint-conditional" : "breakpoint";
    const parts = [];
    if (robot !== null) parts.push(`robot ${robot}`);
    if (condition) parts.push(`when ${condition}`);
    if (hits) parts.push(`from hit ${hits}`);
    dot.title = "breakpoint" + (parts.length ? ": " + parts.join(", ") : "")
      + " (click: remove, right-click: options)";
    return dot;
  }
}

class PausedMarker extends GutterMarker {
  constructor(paused) {
    super();
    this.paused = paused;
  }

  eq(other) {
    return JSON.stringify(other.paused) === JSON.stringify(this.paused);
  }

  toDOM() {
    const arrow = document.createElement("div");
    arrow.className = "paused-arrow";
    arrow.textContent = "➜";
    arrow.title = `paused: robot ${this.paused.robot} (${this.paused.reason})`;
    return arrow;
  }
}

class SpacerMarker extends GutterMarker {
  toDOM() {
    const spacer = document.createElement("div");
    spacer.className = "breakpoint-spacer";  // a dot's width, never shown
    return spacer;
  }
}

const NO_OPTIONS = { condition: null, robot: null, hit_count: null };
const setBreakpointsEffect = StateEffect.define();
const setPausedEffect = StateEffect.define();

const breakpointField = StateField.define({
  create: () => RangeSet.empty,
  update(set, transaction) {
    let value = set.map(transaction.changes);
    for (const effect of transaction.effects) if (effect.is(setBreakpointsEffect)) value = effect.value;
    return value;
  },
});

/** {line: number, paused, markers: RangeSet, lines: DecorationSet} or null when running. */
const pausedField = StateField.define({
  create: () => null,
  update(value, transaction) {
    for (const effect of transaction.effects) if (effect.is(setPausedEffect)) return effect.value;
    if (value === null || !transaction.docChanged) return value;
    return { ...value, markers: value.markers.map(transaction.changes),
      lines: value.lines.map(transaction.changes) };
  },
  provide: (field) => EditorView.decorations.from(field, (value) => value ? value.lines : Decoration.none),
});

/** The breakpoints shown, as the server's JSON list (lines from 1, in order). */
export function breakpointList(state) {
  const list = [];
  const cursor = state.field(breakpointField).iter();
  for (; cursor.value !== null; cursor.next()) {
    list.push({ line: state.doc.lineAt(cursor.from).number, ...cursor.value.options });
  }
  return list;
}

function markersOf(doc, list) {
  const ranges = [];
  for (const b of [...list].sort((a, c) => a.line - c.line)) {
    if (b.line < 1 || b.line > doc.lines) continue;
    const options = { condition: b.condition ?? null, robot: b.robot ?? null, hit_count: b.hit_count ?? null };
    ranges.push(new BreakpointMarker(options).range(doc.line(b.line).from));
  }
  return RangeSet.of(ranges, true);
}

/** The transaction spec that shows exactly `list` (the server's JSON) as the breakpoints. */
export function setBreakpoints(state, list) {
  return { effects: setBreakpointsEffect.of(markersOf(state.doc, list)) };
}

/** The breakpoint list with line `line`'s breakpoint toggled, or given `options` (null: removed). */
function withLine(state, line, options) {
  const others = breakpointList(state).filter((b) => b.line !== line);
  if (options === undefined) {
    const had = others.length !== breakpointList(state).length;
    return had ? others : [...others, { line, ...NO_OPTIONS }];
  }
  return options === null ? others : [...others, { line, ...options }];
}

/** The transaction spec that shows where the debugger paused (`paused`: {line, robot, reason}
 *  or null), placed on line `paused.line` of the text shown. */
export function showPaused(state, paused) {
  if (!paused || paused.line < 1 || paused.line > state.doc.lines) {
    return { effects: setPausedEffect.of(null) };
  }
  const from = state.doc.line(paused.line).from;
  return {
    effects: setPausedEffect.of({
      line: paused.line, paused,
      markers: RangeSet.of([new PausedMarker(paused).range(from)]),
      lines: Decoration.set([Decoration.line({ class: "paused-line" }).range(from)]),
    }),
  };
}

/** The editor extensions for breakpoints; `onChange(list)` runs after the user changes them. */
export function breakpointsExtension(onChange) {
  const form = document.getElementById("breakpoint-form");
  let formLine = null;

  function change(view, list) {
    view.dispatch(setBreakpoints(view.state, list));
    onChange(breakpointList(view.state));
  }

  function openForm(view, line, event) {
    formLine = line;
    const current = breakpointList(view.state).find((b) => b.line === line) || NO_OPTIONS;
    form.querySelector("#bp-line").textContent = String(line);
    form.querySelector("#bp-condition").value = current.condition || "";
    form.querySelector("#bp-robot").value = current.robot ?? "";
    form.querySelector("#bp-hits").value = current.hit_count ?? "";
    form.hidden = false;
    form.style.top = `${Math.max(0, event.clientY - 10)}px`;
    form.style.left = `${event.clientX + 12}px`;
    form.querySelector("#bp-condition").focus();
    form.view = view;
  }

  function whole(text) {
    const value = text.trim();
    return /^\d+$/.test(value) ? Number(value) : null;
  }

  form.querySelector("#bp-save").addEventListener("click", () => {
    const options = {
      condition: form.querySelector("#bp-condition").value.trim() || null,
      robot: whole(form.querySelector("#bp-robot").value),
      hit_count: whole(form.querySelector("#bp-hits").value) || null,
    };
    form.hidden = true;
    change(form.view, withLine(form.view.state, formLine, options));
  });
  form.querySelector("#bp-remove").addEventListener("click", () => {
    form.hidden = true;
    change(form.view, withLine(form.view.state, formLine, null));
  });
  form.querySelector("#bp-cancel").addEventListener("click", () => { form.hidden = true; });
  form.addEventListener("keydown", (event) => {
    if (event.key === "Enter") form.querySelector("#bp-save").click();
    if (event.key === "Escape") form.hidden = true;
  });

  const lineOf = (view, block) => view.state.doc.lineAt(block.from).number;
  return [
    breakpointField,
    pausedField,
    gutter({
      class: "bbz-breakpoints",
      markers: (view) => {
        const paused = view.state.field(pausedField);
        const dots = view.state.field(breakpointField);
        return paused ? RangeSet.join([dots, paused.markers]) : dots;
      },
      initialSpacer: () => new SpacerMarker(),
      renderEmptyElements: true,  // every line is a target for a click
      domEventHandlers: {
        mousedown(view, block, event) {
          if (event.button !== 0) return false;
          change(view, withLine(view.state, lineOf(view, block)));
          return true;
        },
        contextmenu(view, block, event) {
          event.preventDefault();
          openForm(view, lineOf(view, block), event);
          return true;
        },
      },
    }),
  ];
}
