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
      playNext();
    });
    on(document.querySelector(`button[data-play="${slot}"]`), "click", () => {
      pauseOthers(video);
      video.currentTime = 0;
      video.play();
    });
  });
  sliders.forEach((slider) => {
    // The slider's number beside it, and on its clip's tab (a phone shows one clip at a time).
    const output = document.querySelector(`output[for="${slider.id}"]`);
    const tabValue = document.querySelector(`.clip-tabs [data-value="${slider.dataset.slot}"]`);
    on(slider, "input", () => {
      output.value = slider.value;
      tabValue.textContent = slider.value;
      field(`moved-${slider.dataset.slot}`).value = "1";  // even a move back to the start counts
      update();
    });
  });
  // The clips play by themselves, each once, in the page's order (where the participant has
  // not asked for reduced motion): the first on arrival, the next when one ends. On a narrow
  // screen, where one clip is shown at a time, only the shown clip plays by itself.
  const autoplay = !window.matchMedia("(prefers-reduced-motion: reduce)").matches;
  const shown = (video) => video.closest(".clip").offsetParent !== null;
  const playNext = () => {
    if (!autoplay || videos.some((video) => !video.paused && !video.ended)) return;
    const next = videos.find((video) => !ended.has(video.dataset.slot) && shown(video));
    if (next) next.play().catch(() => {});  // a browser that refuses: the play buttons remain
  };
  // On a narrow screen the clips would stack beyond the screen: one is shown at a time, with
  // tabs to switch between them (every slider stays in the form, hidden or not; each tab
  // shows its clip's rating).
  const tabs = document.querySelector(".clip-tabs");
  if (tabs) {
    const sections = [...document.querySelectorAll(".clips > .clip")];
    const buttons = [...tabs.querySelectorAll("[data-tab]")];
    const show = (slot) => {
      videos.forEach((video) => video.pause());
      sections.forEach((section) => section.classList.toggle("current", section.id === `clip-${slot}`));
      buttons.forEach((button) => {
        const selected = button.dataset.tab === slot;
        button.setAttribute("aria-selected", String(selected));
        button.tabIndex = selected ? 0 : -1;  // the chosen tab alone in the Tab order; the arrows move along them
      });
      playNext();
    };
    buttons.forEach((button) => on(button, "click", () => show(button.dataset.tab)));
    sections.forEach((section) => section.setAttribute("role", "tabpanel"));
    // ARIA's tabs pattern: left and right arrows (round the ends), Home and End choose a tab.
    on(tabs, "keydown", (event) => {
      const at = buttons.indexOf(document.activeElement);
      const to = { ArrowRight: at + 1, ArrowLeft: at - 1, Home: 0, End: buttons.length - 1 }[event.key];
      if (at < 0 || to === undefined || event.altKey || event.ctrlKey || event.metaKey) return;
      event.preventDefault();
      const next = buttons[(to + buttons.length) % buttons.length];
      next.focus();
      show(next.dataset.tab);
    });
    document.querySelector(".clips").classList.add("tabbed");
    tabs.hidden = false;
    show(buttons[0].dataset.tab);
  } else {
    playNext();
  }
  // A graded preference: the choice first (A, B or none), then, for A or B, how strong it is;
  // the strength's button sends the answer, with the choice.
  const strength = form.querySelector("fieldset.strength");
  const choice = document.getElementById("choice");
  on(form, "submit", (event) => {
    const submitter = event.submitter;
    if (strength && submitter && submitter.name === "answer") {
      if (submitter.value !== "none") {
        event.preventDefault();
        choice.value = submitter.value;
        choice.disabled = false;
        form.querySelectorAll("button[name=answer]").forEach((button) => {
          button.setAttribute("aria-pressed", String(button === submitter));
        });
        strength.hidden = false;
        strength.scrollIntoView({ block: "nearest" });
        return;
      }
      choice.disabled = true;  // no preference has no strength
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
