/* The researcher's pages: the study settings that matter for the chosen design, and
   how far a large upload (a checkpoint, submitted motion) has got. Without scripts,
   every setting shows and uploads are plain form posts. */
(function () {
  "use strict";

  // Each setting that only some designs read names them (data-designs); the others hide it.
  const settings = document.getElementById("study-settings");
  if (settings) {
    const design = settings.elements.namedItem("design");
    const show = () => {
      for (const row of settings.querySelectorAll("[data-designs]")) {
        row.hidden = !row.dataset.designs.split(" ").includes(design.value);
      }
    };
    design.addEventListener("change", show);
    // A hidden switch belongs to another design: it is sent as off, which the server expects.
    settings.addEventListener("submit", () => {
      for (const box of settings.querySelectorAll("[data-designs][hidden] input[type=checkbox]")) box.checked = false;
    });
    show();
  }

  // An upload form with a progress bar sends its files by XMLHttpRequest, to show how much
  // has gone; the answer (the page after a redirect, or the form with its errors) then
  // replaces this page as a plain post's would.
  for (const form of document.querySelectorAll("form[data-upload-progress]")) {
    const bar = form.querySelector("progress"), status = form.querySelector(".upload-status");
    form.addEventListener("submit", (event) => {
      const chosen = [...form.querySelectorAll("input[type=file]")].some((input) => input.files.length);
      if (!chosen) return;  // the server says what is missing
      event.preventDefault();
      const button = form.querySelector("button[type=submit]");
      const request = new XMLHttpRequest();
      // getAttribute: these forms hold an input named "action", which form.action would be.
      request.open("POST", form.getAttribute("action") || location.href);
      request.upload.addEventListener("progress", (progress) => {
        if (!progress.lengthComputable) return;
        bar.max = progress.total;
        bar.value = progress.loaded;
        status.textContent = `${Math.round(100 * progress.loaded / progress.total)} % sent`;
      });
      request.upload.addEventListener("load", () => {
        bar.value = bar.max;
        status.textContent = "Sent: the server is checking the file…";
      });
      request.addEventListener("load", () => {
        history.replaceState(null, "", request.responseURL);
        document.open();
        document.write(request.responseText);
        document.close();
      });
      request.addEventListener("error", () => {
        status.textContent = "The upload stopped: the connection to the server was lost. Try again.";
        button.disabled = false;
      });
      bar.hidden = false;
      bar.value = 0;
      status.textContent = "Starting the upload…";
      button.disabled = true;
      request.send(new FormData(form));
    });
  }
})();
