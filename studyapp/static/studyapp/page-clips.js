// The clips of a side-by-side or pairwise page: one plays at a time, each clip's times
// are recorded (seconds after the page was shown; the server judges early answers with
// them), and the answer can be sent only once every clip has been played to its end.
(function () {
  const form = document.getElementById("page-form");
  const videos = [...document.querySelectorAll("video[data-slot]")];
  const field = (name) => form.elements.namedItem(name);
  const now = () => (performance.now() / 1000).toFixed(3);
  const submits = [...form.querySelectorAll("button[type=submit]")];
  const note = document.getElementById("play-note");
  const ended = new Set();
  const update = () => {
    const ready = ended.size === videos.length;
    submits.forEach((button) => { button.disabled = !ready; });
    note.hidden = ready;
  };
  // Paused at once, not only on the "play" event (queued after play() returns), so that two
  // clips never play together, not even for a moment.
  const pauseOthers = (video) => videos.forEach((other) => { if (other !== video) other.pause(); });
  videos.forEach((video) => {
    const slot = video.dataset.slot;
    video.addEventListener("play", () => pauseOthers(video));  // started some other way (native controls)
    video.addEventListener("playing", () => { if (!field(`started_s-${slot}`).value) field(`started_s-${slot}`).value = now(); });
    video.addEventListener("ended", () => {
      if (!field(`ended_s-${slot}`).value) field(`ended_s-${slot}`).value = now();
      ended.add(slot);
      update();
    });
    document.querySelector(`button[data-play="${slot}"]`).addEventListener("click", () => {
      pauseOthers(video);
      video.currentTime = 0;
      video.play();
    });
  });
  form.querySelectorAll("input[type=range]").forEach((slider) => {
    const output = form.querySelector(`output[for="${slider.id}"]`);
    slider.addEventListener("input", () => { output.value = slider.value; });
  });
  let sent = false;
  form.addEventListener("submit", (event) => {
    const strengths = [...form.querySelectorAll("input[name=strength]")];
    const choice = event.submitter ? event.submitter.value : "";
    if (choice === "none") strengths.forEach((radio) => { radio.checked = false; });
    else if (strengths.length && !strengths.some((radio) => radio.checked)) {
      event.preventDefault();
      document.getElementById("strength-note").hidden = false;
      return;
    }
    if (sent) { event.preventDefault(); return; }
    sent = true;
    videos.forEach((video) => {
      const slot = video.dataset.slot;
      field(`answered_s-${slot}`).value = now();
      field(`played_until_s-${slot}`).value = video.currentTime.toFixed(3);
    });
  });
  update();
})();
