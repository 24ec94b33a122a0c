// A page of clips answered with one request, the next page swapped in without a reload.
//
// The page's own script (clip-page.js, page-clips.js) says how a page is set up
// (window.studyappSetUpPage); this one sets up the page on load, and sends its form with
// the Studyapp-Next-Page header. The server answers with the next page itself where that
// is another page of clips (its title and main part, rendered as a page loaded anew
// renders them, and marked shown by the server's clock as the answer is stored), whose
// main part replaces this one's: the clips that the
// page had been loading in its hidden "upcoming" videos take the new clips' places, so they
// play at once. Any other next page (questions, the end) comes as a redirect, followed by
// loading the page; a refused answer (too early, say) shows the server's reason on the
// page, which stays. Without this script the form posts and is redirected as any form.
// Its words are the page's (window.studyappText, in the study's language).
(function () {
  const form = () => document.querySelector("form[data-next-page]");
  if (!form() || !window.studyappSetUpPage) return;
  let page = new AbortController();
  window.studyappSetUpPage(0, page.signal);  // the times of a page loaded anew count from its navigation

  // The next page's videos, each replaced by this page's upcoming video of the same clip:
  // the element that has already loaded it, given the new one's attributes.
  const adoptLoaded = (main, upcoming) => {
    main.querySelectorAll("video[src]:not([data-upcoming])").forEach((video) => {
      const loaded = upcoming.get(video.getAttribute("src"));
      if (!loaded) return;
      upcoming.delete(video.getAttribute("src"));
      loaded.removeAttribute("data-upcoming");
      [...video.attributes].forEach(({ name, value }) => { if (name !== "src") loaded.setAttribute(name, value); });
      video.replaceWith(loaded);  // moving a video keeps what it has loaded; setting its src would not
    });
  };

  const swap = (next) => {
    const upcoming = new Map([...document.querySelectorAll("video[data-upcoming]")].map(
      (video) => [video.getAttribute("src"), video]));
    const main = document.importNode(next.querySelector("main"), true);
    adoptLoaded(main, upcoming);
    page.abort();
    page = new AbortController();
    document.querySelector("main").replaceWith(main);
    document.title = next.title;
    window.scrollTo(0, 0);
    window.studyappSetUpPage(performance.now(), page.signal);
    document.dispatchEvent(new Event("studyapp:page"));
  };

  const refused = (sent, text, back) => {
    let notice = document.getElementById("answer-refused");
    if (!notice) {
      notice = document.createElement("p");
      notice.id = "answer-refused";
      notice.className = "notice bad";
      notice.setAttribute("role", "alert");
      sent.before(notice);
    }
    notice.textContent = text;
    if (back) {
      const link = document.createElement("a");
      link.href = back;
      link.textContent = studyappText.back;
      notice.append(" ", link);
    }
    delete sent.dataset.sent;  // the participant may answer again
  };

  const send = async (sent, submitter) => {
    const data = new FormData(sent);
    if (submitter && submitter.name) data.append(submitter.name, submitter.value);
    let response;
    try {
      response = await fetch(sent.action, {
        method: "POST", body: new URLSearchParams(data), credentials: "same-origin", redirect: "manual",
        headers: { "Studyapp-Next-Page": "in-place" },
      });
    } catch (error) {
      refused(sent, studyappText.not_sent);
      return;
    }
    if (response.type === "opaqueredirect") {  // the next page is no page of clips: load it
      location.assign(sent.dataset.nextPage);
      return;
    }
    const next = new DOMParser().parseFromString(await response.text(), "text/html");
    if (!response.ok) {
      const reason = next.querySelector(".notice");
      refused(sent, reason ? reason.textContent : studyappText.format(studyappText.not_taken, { status: response.status }),
              next.querySelector("a.button")?.getAttribute("href"));
    } else if (next.querySelector("main form[data-next-page]")) {
      swap(next);
    } else {
      location.assign(sent.dataset.nextPage);
    }
  };

  document.addEventListener("submit", (event) => {
    const sent = event.target;
    // The page's script refused the submission (a clip not played, an answer sent already),
    // or a preview, whose forms lead to its next page.
    if (event.defaultPrevented || sent !== form()) return;
    event.preventDefault();
    send(sent, event.submitter);
  });
})();
