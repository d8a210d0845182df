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
