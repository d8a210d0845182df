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
