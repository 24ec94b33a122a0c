// A page of one clip (the single design): the clip plays by itself unless motion is reduced,
// its times are recorded (seconds after the page was shown; the server judges early answers
// with them), the answer buttons unlock at the clip's first end where the study asks, and the
// keys answer too. next-page.js sets the page up, on load and again for each page it swaps
// in: ``shownAt`` is the moment (performance.now()) the page was shown, ``signal`` ends the
// page's listeners.
window.studyappSetUpPage = (shownAt, signal) => {
  const video = document.getElementById("clip");
  const form = document.getElementById("rating-form");
  const on = (target, type, listener) => target.addEventListener(type, listener, { signal });
  const field = (name) => form.elements.namedItem(name);
  const now = () => ((performance.now() - shownAt) / 1000).toFixed(3);
  on(video, "playing", () => { if (!field("started_s").value) field("started_s").value = now(); });
  const points = [...form.querySelectorAll("button[name=value]")];
  const unlock = () => {  // the buttons are locked until the clip's first end where the study asks
    points.forEach((button) => { button.disabled = false; });
    const hint = document.getElementById("lock-hint");
    if (hint) hint.hidden = true;
  };
  on(video, "ended", () => {
    if (!field("ended_s").value) field("ended_s").value = now();
    if (document.fullscreenElement) document.exitFullscreen();
    unlock();
  });
  // The clip plays by itself, started here rather than by an autoplay attribute: one the page
  // started could play (and a short one end) before this script arrived, its start unrecorded and
  // reduced motion not honoured. Where the participant asked for reduced motion the clip waits
  // for its button, as the clips of a page of several do (page-clips.js).
  const replay = document.getElementById("replay");
  if (window.matchMedia("(prefers-reduced-motion: reduce)").matches) {
    const again = replay.textContent;
    replay.textContent = replay.dataset.firstLabel;
    on(video, "playing", () => { replay.textContent = again; });
  } else {  // nothing has played it yet: neither a page's new clip nor a hidden one adopted (next-page.js)
    video.play().catch(() => {});
  }

  // A clip that fails to load says so and can be fetched again.
  const loadError = document.getElementById("load-error");
  const failed = () => { loadError.hidden = false; };
  on(video, "error", failed);
  if (video.error) failed();
  on(document.getElementById("retry"), "click", () => {
    loadError.hidden = true;
    video.load();
    video.play().catch(() => {});
  });

  on(replay, "click", () => { video.currentTime = 0; video.play(); });
  on(document.getElementById("enlarge"), "click", () => {
    // The whole screen where the browser allows it; iPhones only let the video itself go full screen.
    const stage = document.getElementById("stage");
    if (stage.requestFullscreen) stage.requestFullscreen().catch(() => video.webkitEnterFullscreen?.());
    else video.webkitEnterFullscreen?.();
  });
  on(form, "submit", (event) => {
    if (form.dataset.sent) { event.preventDefault(); return; }  // once (next-page.js clears it on a refusal)
    form.dataset.sent = "yes";
    // A key pressed as the clip ends can come before the queued "ended" event: the clip has still ended first.
    if (video.ended && !field("ended_s").value) field("ended_s").value = now();
    field("answered_s").value = now();
    field("played_until_s").value = video.currentTime.toFixed(3);
  });
  on(document, "keydown", (event) => {
    if (event.altKey || event.ctrlKey || event.metaKey) return;
    const key = event.key === "0" ? "10" : event.key;
    const button = points.find((b) => b.value === key);
    if (button && !button.disabled) { event.preventDefault(); button.click(); }
  });
};
