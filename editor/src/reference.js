// The Buzz reference page (/editor/reference): docs/buzz-reference.md's text, which the server
// renders from bbzide/compiler/reference.py and bbzide/worlds/reference.py (the tables the
// editor's completion and hover read), turned into HTML here by `marked`.
//
// Design: the Markdown is ours and comes from the IDE's own server; raw HTML in it is shown as
// text all the same (the renderer escapes it), so the page never runs markup from the file.

import { marked } from "marked";

const escapeHtml = (text) => text.replace(/&/g, "&amp;").replace(/</g, "&lt;").replace(/>/g, "&gt;");
marked.use({ renderer: { html: ({ text }) => escapeHtml(text) } });

async function show() {
  const box = document.getElementById("reference");
  const answer = await fetch("reference.md", { credentials: "same-origin" });
  if (!answer.ok) {
    box.textContent = `could not load the reference (${answer.status})`;
    return;
  }
  box.innerHTML = marked.parse(await answer.text());
  // Each heading gets an id so that the editor can link to a section (#built-ins, ...).
  for (const heading of box.querySelectorAll("h2, h3")) {
    heading.id = heading.textContent.toLowerCase().replace(/[^a-z0-9]+/g, "-").replace(/^-|-$/g, "");
  }
  if (window.location.hash) document.getElementById(window.location.hash.slice(1))?.scrollIntoView();
}

show();
