"""``{% script_text %}``: the words the participant pages' scripts show, in the page's language.

The scripts (static/studyapp/*.js and the pages' own) never hold a sentence of their own:
they read ``window.studyappText``, which this tag fills from the study's language's
catalogue (a JSON element, then one line that reads it). A text with values names them
as ``%(name)s``, which ``studyappText.format(text, {name: value})`` fills in.
"""

from django import template
from django.utils.html import json_script
from django.utils.safestring import SafeString, mark_safe
from django.utils.translation import gettext_lazy as _

register = template.Library()

SCRIPT_TEXT = {
    "yes": _("yes"),
    "no": _("no"),
    "no_size": _("no (%(width)s × %(height)s)"),
    "screen_too_small": _("This study needs a screen %(need)s. Please open the link on a larger screen, or turn "
                          "your device."),
    "video_unplayable": _("Your browser cannot play this study's videos. Please try another browser (a recent "
                          "Chrome, Firefox, Safari or Edge)."),
    "copied": _("Copied."),
    "selected": _("Selected: copy it with your device's copy command."),
    "move_sliders": _("Move each clip's slider to your rating before you answer (not yet moved: clip %(clips)s)."),
    "back": _("Back to the study"),
    "not_sent": _("Your answer could not be sent. Please check your connection and answer again."),
    "not_taken": _("The server did not take the answer (%(status)s)."),
}

# Reads the JSON element into window.studyappText, with the function that fills in a text's values.
READER = ('<script>window.studyappText = Object.assign(JSON.parse(document.getElementById("studyapp-text")'
          '.textContent), {format: (text, values) => text.replace(/%\\((\\w+)\\)s/g, (all, name) => '
          'String(values[name]))});</script>')


@register.simple_tag
def script_text() -> SafeString:
    return json_script({name: str(text) for name, text in SCRIPT_TEXT.items()}, "studyapp-text") + mark_safe(READER)
