// The Buzz language for CodeMirror: a stream tokenizer (our own, no grammar generator) that
// colours Buzz, an auto-indent, and a lexer over a whole text that the
// completion's scope scan (completion.js) and the auto-indent read.
//
// Design: Buzz's lexical rules are few ('#' comments to the end of the line, strings in either
// quote with backslash escapes and raw newlines, numbers = a digit then digits and dots,
// names = a letter or '_' then letters, digits, '_'), so one hand-written tokenizer serves both
// the highlighter (line by line, through StreamLanguage) and the scope scan (whole text).

import { StreamLanguage, indentService } from "@codemirror/language";
import { Tag, tags, tagHighlighter } from "@lezer/highlight";

export const KEYWORDS = new Set(["var", "if", "else", "function", "return", "for", "while",
  "and", "or", "not", "nil", "include"]);
const NAME_START = /[A-Za-z_]/;
const NAME_PART = /[A-Za-z0-9_]/;
const OPERATORS = /[-+*/%^<>=!&|~]/;
const OPENING = "({[";
const CLOSING = ")}]";

/** A built-in or host function name (coloured apart from the script's own names). */
export const builtinTag = Tag.define(tags.variableName);

/** Token classes as the page's stylesheet names them (tok-keyword, tok-builtin, ...). */
export const buzzHighlighter = tagHighlighter([
  { tag: tags.keyword, class: "tok-keyword" },
  { tag: builtinTag, class: "tok-builtin" },
  { tag: tags.number, class: "tok-number" },
  { tag: tags.string, class: "tok-string" },
  { tag: tags.comment, class: "tok-comment" },
  { tag: tags.operator, class: "tok-operator" },
]);

/**
 * The Buzz StreamLanguage; `builtins` (a Set of names) are coloured as built-ins: the first part
 * of every built-in (`neighbors` of `neighbors.broadcast`) and the world's host functions.
 */
export function buzzLanguage(builtins) {
  return StreamLanguage.define({
    name: "buzz",
    startState: () => ({ quote: null }),  // the quote of a string still open at a line's end
    copyState: (state) => ({ ...state }),
    token(stream, state) {
      if (state.quote !== null) return continueString(stream, state);
      if (stream.eatSpace()) return null;
      const c = stream.next();
      if (c === "#") { stream.skipToEnd(); return "comment"; }
      if (c === '"' || c === "'") { state.quote = c; return continueString(stream, state); }
      if (/[0-9]/.test(c)) { stream.eatWhile(/[0-9.]/); return "number"; }
      if (NAME_START.test(c)) {
        stream.eatWhile(NAME_PART);
        const word = stream.current();
        if (KEYWORDS.has(word)) return "keyword";
        const afterDot = stream.start > 0 && stream.string[stream.start - 1] === ".";
        return !afterDot && builtins.has(word) ? "buzzBuiltin" : "variableName";
      }
      if (OPENING.includes(c) || CLOSING.includes(c)) return "bracket";
      if (OPERATORS.test(c)) { stream.eatWhile(OPERATORS); return "operator"; }
      return "punctuation";
    },
    // (not "builtin": CodeMirror reads that legacy name as variableName.standard)
    tokenTable: { buzzBuiltin: builtinTag },
    languageData: {
      commentTokens: { line: "#" },
      indentOnInput: /^\s*[}\])]$/,
    },
  });
}

/**
 * Auto-indent: one unit per bracket left open before the line (strings and comments aside); a
 * line starting with a closing bracket goes back a level. Read from the whole text before the
 * line, so it holds wherever the editor asks (Enter, a typed "}", a paste).
 */
export const buzzIndentation = indentService.of((context, pos) => {
  let depth = 0;
  for (const token of lexBuzz(context.state.doc.sliceString(0, pos))) {
    if (token.kind !== "punct") continue;
    if (OPENING.includes(token.text)) depth++;
    else if (CLOSING.includes(token.text)) depth = Math.max(0, depth - 1);
  }
  const first = context.textAfterPos(pos).trimStart().charAt(0);
  const closes = first !== "" && CLOSING.includes(first) ? 1 : 0;
  return Math.max(0, depth - closes) * context.unit;
});

function continueString(stream, state) {
  while (!stream.eol()) {
    const c = stream.next();
    if (c === "\\") { stream.next(); continue; }
    if (c === state.quote) { state.quote = null; break; }
  }
  return "string";
}

/**
 * Every token of `text` with its offsets: {kind, text, from, to}, kind among name, keyword,
 * number, string, comment, punct (brackets, operators, dots, commas). Whitespace is skipped.
 */
export function lexBuzz(text) {
  const tokens = [];
  let i = 0;
  const n = text.length;
  while (i < n) {
    const start = i;
    const c = text[i];
    let kind;
    if (c === "#") {
      while (i < n && text[i] !== "\n") i++;
      kind = "comment";
    } else if (c === '"' || c === "'") {
      i++;
      while (i < n && text[i] !== c) { if (text[i] === "\\") i++; i++; }
      i = Math.min(n, i + 1);
      kind = "string";
    } else if (/[0-9]/.test(c)) {
      while (i < n && /[0-9.]/.test(text[i])) i++;
      kind = "number";
    } else if (NAME_START.test(c)) {
      while (i < n && NAME_PART.test(text[i])) i++;
      kind = KEYWORDS.has(text.slice(start, i)) ? "keyword" : "name";
    } else if (/\s/.test(c)) {
      i++;
      continue;
    } else {
      i++;
      if (OPERATORS.test(c)) while (i < n && OPERATORS.test(text[i])) i++;
      kind = "punct";
    }
    tokens.push({ kind, text: text.slice(start, i), from: start, to: i });
  }
  return tokens;
}
