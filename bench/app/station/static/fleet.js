// The lab page: the benches' table, rendered by the server (the same template the page
// was served with) and sent over server-sent events whenever a bench delivers; the script
// only puts it in place. `window.fleet` holds the latest update, for the browser test.
"use strict";
(function () {
  const root = document.getElementById("fleet");
  if (!root) return;
  const fleet = (window.fleet = { updates: 0, benches: null });
  const source = new EventSource(root.dataset.stream);
  source.addEventListener("fleet", (ev) => {
    const data = JSON.parse(ev.data);
    root.innerHTML = data.html;
    fleet.benches = data.benches;
    fleet.updates += 1;
  });
})();
