// Refresh the live part of a page without reloading it: fetch its HTML fragment (same origin,
// the session cookie) and swap it in. A session that expired sends the browser to the login page.
(function () {
  "use strict";
  function refresh(box) {
    var active = document.activeElement;
    if (active && active.tagName === "SELECT" && box.contains(active)) { return; }  // a choice being made
    var url = box.getAttribute("data-refresh");
    fetch(url, { credentials: "same-origin", headers: { "Accept": "text/html" }, cache: "no-store" })
      .then(function (r) {
        if (r.redirected || r.status === 401) { window.location.assign("/dashboard/login"); return null; }
        return r.ok ? r.text() : null;
      })
      .then(function (html) {
        if (html !== null && html !== undefined) { box.innerHTML = html; box.setAttribute("data-refreshed", String(Date.now())); }
      })
      .catch(function () { /* the service is restarting: try again at the next tick */ });
  }
  document.addEventListener("DOMContentLoaded", function () {
    document.querySelectorAll("[data-refresh]").forEach(function (box) {
      var seconds = parseInt(box.getAttribute("data-interval") || "30", 10);
      if (seconds > 0) { window.setInterval(function () { refresh(box); }, seconds * 1000); }
    });
  });
})();
