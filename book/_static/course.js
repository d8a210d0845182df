/* The phone menus' focus (WCAG 2.1, success criterion 2.4.3 Focus Order). At narrow widths the
   theme shows the contents in a dialog, opened by the button that toggles the sidebar; Escape
   closes it, but leaves the keyboard focus on the page's body, so a keyboard user starts again
   from the top of the page. Give the focus back to the button that opened the dialog. */
document.addEventListener("DOMContentLoaded", () => {
  let opener = null;
  document.addEventListener("click", (event) => {
    const button = event.target.closest("button.sidebar-toggle");
    if (button) opener = button;
  }, true);
  for (const id of ["pst-primary-sidebar-modal", "pst-secondary-sidebar-modal"]) {
    const dialog = document.getElementById(id);
    if (!dialog) continue;
    dialog.addEventListener("close", () => setTimeout(() => {
      const lost = !document.activeElement || document.activeElement === document.body;
      if (lost && opener && opener.isConnected) opener.focus();
    }));
  }
});

/* Figures on a phone (labsupport.book.show_figure). A figure drawn for a 744 px column is shown
   358 px wide on a phone, and its tick labels shrink to about 3 px. Where a figure is shown
   narrower than it was drawn, a "Full size" toggle button above it shows it at the size it was
   drawn, in a frame that scrolls sideways (and takes the keyboard's focus, so the arrow keys
   scroll it too: the button comes first, so Tab goes on from it into the frame); pressed again,
   the figure fits the page again. Where the figure fits, the button is hidden. Each button's
   name says which figure it is for ("Full size, figure 2 of 7"), as a screen reader's list of
   buttons shows them side by side. */
document.addEventListener("DOMContentLoaded", () => {
  const figures = document.querySelectorAll("figure.course-figure");
  for (const [k, figure] of figures.entries()) {
    const img = figure.querySelector("img");
    if (!img) continue;
    const frame = document.createElement("div");
    frame.className = "course-figure-frame";
    img.replaceWith(frame);
    frame.append(img);
    const button = document.createElement("button");
    button.type = "button";
    button.className = "course-figure-size";
    button.textContent = "Full size";
    button.setAttribute("aria-label", `Full size, figure ${k + 1} of ${figures.length}`);
    button.setAttribute("aria-pressed", "false");
    button.addEventListener("click", () => {
      const full = figure.classList.toggle("full-size");
      button.setAttribute("aria-pressed", String(full));
      if (full) {
        frame.tabIndex = 0;
        frame.setAttribute("role", "group");
        frame.setAttribute("aria-label", "The figure at full size: scroll sideways to see all of it");
      } else {
        for (const name of ["tabindex", "role", "aria-label"]) frame.removeAttribute(name);
      }
    });
    frame.before(button);
    const drawn = Number(img.getAttribute("width"));
    const update = () => {
      button.hidden = !figure.classList.contains("full-size") && img.clientWidth >= drawn - 1;
    };
    new ResizeObserver(update).observe(figure);
    update();
  }
});

/* Search results (Sphinx 7.4's searchtools.js). Sphinx quotes 240 characters of a page's main
   block around the first place its stemmed search words occur as written. That block opens with
   the header's buttons, and a stem is seldom written so ("graviti" for "gravity"), so every
   result quoted the header ("...Colab"), and a quote that did reach the text showed formulas as
   their TeX source (\(mgr\cos\theta\)). Here the quote is taken from the article, around the
   longest start of a search word that occurs in it, with its white space collapsed, a dash after
   each heading (which ran into the text that follows) and each formula's TeX read as text. */
const TEX_SYMBOLS = {
  alpha: "α", beta: "β", gamma: "γ", delta: "δ", epsilon: "ε", zeta: "ζ", eta: "η", theta: "θ",
  lambda: "λ", mu: "μ", nu: "ν", pi: "π", rho: "ρ", sigma: "σ", tau: "τ", phi: "φ", omega: "ω",
  Delta: "Δ", Lambda: "Λ", Omega: "Ω", cdot: "·", times: "×", approx: "≈", le: "≤", leq: "≤",
  ge: "≥", geq: "≥", ne: "≠", to: "→", infty: "∞", int: "∫", sum: "∑", sqrt: "√", pm: "±",
};
const TEX_WORDS = new Set(["sin", "cos", "tan", "arccos", "arcsin", "arctan", "exp", "log", "ln", "det", "max", "min"]);

/* One term of a fraction as text: in brackets unless it is a single symbol or word (k_v, \pi). */
const texAtom = (term) => (/^\\?[A-Za-z0-9_.]+$/.test(term.trim()) ? term : `(${term})`);

/* The combining marks that draw TeX's accents over the letter before them (θ̇, q̈, M̃, x̂). */
const TEX_ACCENTS = { dot: "\u0307", ddot: "\u0308", tilde: "\u0303", hat: "\u0302" };

function texAsText(text) {
  return text
    .replace(/\\(begin|end)\{[^}]*\}/g, " ")
    .replace(/\\(dot|ddot|tilde|hat)\s*\{([^{}]*)\}/g, (_, accent, base) => ` ${base}${TEX_ACCENTS[accent]}`)
    .replace(/\\(dot|ddot|tilde|hat)(?:\s*(\\[A-Za-z]+)|\s+(\w))/g, (_, accent, command, letter) =>
      ` ${command ?? letter}${TEX_ACCENTS[accent]}`)
    .replace(/\\[()[\]]|\$\$?|&/g, " ")
    .replace(/\\operatorname\{([^}]*)\}/g, " $1 ")
    .replace(/\\[dt]?frac\{([^{}]*)\}\{([^{}]*)\}/g, (_, a, b) => `${texAtom(a)}/${texAtom(b)}`)
    .replace(/\\([A-Za-z]+)/g, (_, name) => TEX_SYMBOLS[name] ?? (TEX_WORDS.has(name) ? ` ${name} ` : " "))
    .replace(/\\./g, " ")
    .replace(/[{}]/g, "")
    .replace(/\s+/g, " ")
    .replace(/ ([.,;:!?)])/g, "$1") // a formula's closing \) left a space before the stop after it
    .trim();
}

document.addEventListener("DOMContentLoaded", () => {
  if (typeof Search === "undefined") return;
  Search.makeSearchSummary = (htmlText, keywords, anchor) => {
    const page = new DOMParser().parseFromString(htmlText, "text/html");
    page.querySelectorAll(".headerlink, script, style").forEach((el) => el.remove());
    page.querySelectorAll("h1, h2, h3, h4, h5, h6").forEach((h) => h.append(" — ")); // a heading ends
    const block =
      (anchor && page.querySelector(`article ${anchor}`)) || page.querySelector("article") || page.querySelector("main");
    const text = block ? texAsText(block.textContent) : ""; // Sphinx appends what this returns: never null
    const lower = text.toLowerCase();
    let at = -1;
    for (const word of keywords) {
      for (let n = word.length; at < 0 && n >= Math.min(4, word.length); n--) {
        at = lower.indexOf(word.slice(0, n).toLowerCase());
      }
      if (at >= 0) break;
    }
    const start = Math.max(at - 120, 0);
    const summary = document.createElement("p");
    summary.classList.add("context");
    summary.textContent =
      (start > 0 ? "…" : "") + text.substr(start, 240).trim() + (start + 240 < text.length ? "…" : "");
    return summary;
  };
});

/* Search page and dialog, for screen readers and the keyboard. The line that says how the search
   went ("Search finished, found 6 page(s) ...") is a status, read out when it changes; with no
   result it no longer asks for "categories", which this book has none of. The page's own script
   focused the first search field it found, the one hidden in the closed Ctrl+K dialog, so the
   focus was nowhere: the page's own field takes it. The dialog is named. */
document.addEventListener("DOMContentLoaded", () => {
  document.getElementById("pst-search-dialog")?.setAttribute("aria-label", "Search this book");
  const results = document.getElementById("search-results");
  if (!results) return;
  results.parentElement.querySelector("form.bd-search input")?.focus();
  const tidy = () => {
    const status = results.querySelector("p.search-summary");
    if (!status) return;
    status.setAttribute("role", "status");
    if (/categories/.test(status.textContent)) {
      status.textContent = "No page matches this search. Check the spelling, or try fewer or other words.";
    }
  };
  new MutationObserver(tidy).observe(results, { childList: true, subtree: true, characterData: true });
});
