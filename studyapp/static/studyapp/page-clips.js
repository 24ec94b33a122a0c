// The clips of a side-by-side or pairwise page: one plays at a time, each clip's times
// are recorded (seconds after the page was shown; the server judges early answers with
// them), and the answer can be sent only once every clip has been played to its end.
// next-page.js sets the page up, on load and again for each page it swaps in: ``shownAt``
// is the moment (performance.now()) the page was shown, ``signal`` ends its listeners.
window.studyappSetUpPage = (shownAt, signal) => {
  const form = document.getElementById("page-form");
  const videos = [...document.querySelectorAll("video[data-slot]")];
  const on = (target, type, listener) => target.addEventListener(type, listener, { signal });
  const field = (name) => form.elements.namedItem(name);
  const now = () => ((performance.now() - shownAt) / 1000).toFixed(3);
  const submits = [...form.querySelectorAll("button[type=submit]")];
  const note = document.getElementById("play-note");
  const ended = new Set();
  // The sliders sit beside their clips, outside the form (form="page-form"): form.elements holds them.
  const sliders = [...form.elements].filter((element) => element.type === "range");
  const moved = (slider) => field(`moved-${slider.dataset.slot}`).value === "1";
  const moveNote = document.getElementById("move-note");  // only where each slider must be moved
  const update = () => {
    const played = ended.size === videos.length;
    const unmoved = moveNote ? sliders.filter((slider) => !moved(slider)) : [];
    submits.forEach((button) => { button.disabled = !played || unmoved.length > 0; });
    note.hidden = played;
    if (moveNote) {
      moveNote.hidden = !unmoved.length;
      moveNote.textContent = studyappText.format(studyappText.move_sliders, {
        clips: unmoved.map((slider) => slider.dataset.label).join(", ") });
    }
  };
  // Paused at once, not only on the "play" event (queued after play() returns), so that two
  // clips never play together, not even for a moment.
  const pauseOthers = (video) => videos.forEach((other) => { if (other !== video) other.pause(); });
  videos.forEach((video) => {
    const slot = video.dataset.slot;
    on(video, "play", () => pauseOthers(video));  // started some other way (native controls)
    on(video, "playing", () => { if (!field(`started_s-${slot}`).value) field(`started_s-${slot}`).value = now(); });
    on(video, "ended", () => {
      if (!field(`ended_s-${slot}`).value) field(`ended_s-${slot}`).value = now();
      ended.add(slot);
      document.querySelectorAll(`[data-played="${slot}"]`).forEach((mark) => { mark.hidden = false; });
      update();
    });
    on(document.querySelector(`button[data-play="${slot}"]`), "click", () => {
      pauseOthers(video);
      video.currentTime = 0;
      video.play();
    });
  });
  sliders.forEach((slider) => {
    const output = document.querySelector(`output[for="${slider.id}"]`);
    on(slider, "input", () => {
      output.value = slider.value;
      field(`moved-${slider.dataset.slot}`).value = "1";  // even a move back to the start counts
      update();
    });
  });
  // On a narrow screen the clips would stack beyond the screen: one is shown at a time, with
  // tabs to switch between them (every slider stays in the form, hidden or not).
  const tabs = document.querySelector(".clip-tabs");
  if (tabs) {
    const sections = [...document.querySelectorAll(".clips > .clip")];
    const buttons = [...tabs.querySelectorAll("[data-tab]")];
    const show = (slot) => {
      videos.forEach((video) => video.pause());
      sections.forEach((section) => section.classList.toggle("current", section.id === `clip-${slot}`));
      buttons.forEach((button) => button.setAttribute("aria-selected", String(button.dataset.tab === slot)));
    };
    buttons.forEach((button) => on(button, "click", () => show(button.dataset.tab)));
    document.querySelector(".clips").classList.add("tabbed");
    tabs.hidden = false;
    show(buttons[0].dataset.tab);
  }
  on(form, "submit", (event) => {
    const strengths = [...form.querySelectorAll("input[name=strength]")];
    const choice = event.submitter ? event.submitter.value : "";
    if (choice === "none") strengths.forEach((radio) => { radio.checked = false; });
    else if (strengths.length && !strengths.some((radio) => radio.checked)) {
      event.preventDefault();
      document.getElementById("strength-note").hidden = false;
      return;
    }
    if (form.dataset.sent) { event.preventDefault(); return; }  // once (next-page.js clears it on a refusal)
    form.dataset.sent = "yes";
    videos.forEach((video) => {
      const slot = video.dataset.slot;
      field(`answered_s-${slot}`).value = now();
      field(`played_until_s-${slot}`).value = video.currentTime.toFixed(3);
    });
  });
  update();
};
