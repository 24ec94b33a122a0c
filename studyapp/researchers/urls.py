"""URL map of the researcher's pages (included under ``studies/``)."""

from django.urls import path

from studyapp.researchers import bundle_views, definition_views, figure_views
from studyapp.researchers.crowd import participant_views, platform_views
from studyapp.researchers.results import result_views
from studyapp.researchers.setup import content_views, question_views, stimuli_views, study_views

urlpatterns = [
    path("", study_views.study_list, name="study-list"),
    path("new/", study_views.study_edit, name="study-create"),
    path("new/from-definition/", definition_views.study_from_definition, name="study-from-definition"),
    path("import/", bundle_views.study_import, name="study-import"),
    path("<int:pk>/", study_views.study_edit, name="study-edit"),
    path("<int:pk>/bundle.zip", bundle_views.study_bundle_download, name="study-bundle-download"),
    path("<int:pk>/delete/", study_views.study_delete, name="study-delete"),
    path("<int:pk>/duplicate/", study_views.study_duplicate, name="study-duplicate"),
    path("<int:pk>/systems/", content_views.study_systems, name="study-systems"),
    path("<int:pk>/systems/<int:system>/figure/", figure_views.system_figure, name="study-system-figure"),
    path("<int:pk>/questions/<int:question>/edit/", question_views.study_question_edit, name="study-question-edit"),
    path("<int:pk>/questions/<int:question>/move/", question_views.study_question_move, name="study-question-move"),
    path("<int:pk>/<str:kind>/<int:item>/remove/", study_views.study_remove, name="study-remove"),
    path("<int:pk>/<str:kind>/<int:item>/edit/", study_views.study_item_edit, name="study-item-edit"),
    path("<int:pk>/controls/", content_views.study_controls, name="study-controls"),
    path("<int:pk>/controls.zip", content_views.study_controls_download, name="study-controls-download"),
    path("<int:pk>/stimuli/", stimuli_views.study_stimuli, name="study-stimuli"),
    path("<int:pk>/stimuli/progress.json", stimuli_views.study_progress, name="study-progress"),
    path("<int:pk>/stimuli.zip", stimuli_views.study_stimuli_download, name="study-stimuli-download"),
    path("<int:pk>/stimuli/<int:stimulus_id>/retry/", stimuli_views.stimulus_retry, name="stimulus-retry"),
    path("<int:pk>/monitor/", result_views.study_monitor_page, name="study-monitor"),
    path("<int:pk>/preview/", study_views.study_preview, name="study-preview"),
    path("<int:pk>/preview/<int:index>/", study_views.study_preview, name="study-preview-page"),
    path("<int:pk>/questions/", question_views.study_questions, name="study-questions"),
    path("<int:pk>/participants/", participant_views.study_participants, name="study-participants"),
    path("<int:pk>/participants.csv", participant_views.study_participants_csv, name="study-participants-csv"),
    path("<int:pk>/participants/platform/", platform_views.study_platform, name="study-platform"),
    path("<int:pk>/participants/platform/dry-run/", platform_views.study_platform_dry_run, name="study-platform-dry-run"),
    path("<int:pk>/participants/platform/apply/", platform_views.study_platform_apply, name="study-platform-apply"),
    path("<int:pk>/participants/platform/read/", platform_views.study_platform_read, name="study-platform-read"),
    path("<int:pk>/open/", study_views.study_open, name="study-open"),
    path("<int:pk>/ratings.csv", result_views.study_export, name="study-export"),
    path("<int:pk>/rules.json", result_views.study_rules, name="study-rules"),
    path("<int:pk>/definition.yaml", definition_views.study_definition, name="study-definition"),
    path("<int:pk>/motion.zip", result_views.study_motion_download, name="study-motion-download"),
    path("<int:pk>/adherence/", result_views.study_adherence, name="study-adherence"),
    path("<int:pk>/report/", result_views.study_report, name="study-report"),
    path("<int:pk>/plan/", result_views.study_plan, name="study-plan"),
]
