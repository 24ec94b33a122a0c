"""URL map of the study app."""

from django.conf import settings
from django.contrib import admin
from django.contrib.auth import views as auth_views
from django.urls import include, path

from studyapp.leaderboards.urls import public_urls as public_board_urls
from studyapp.leaderboards.urls import researcher_urls as leaderboard_urls
from studyapp.participants import views as participant_views
from studyapp.participants.path import PATH
from studyapp.researchers import site_views
from studyapp.server import views as server_views

urlpatterns = [
    path("", site_views.gallery, name="gallery"),
    path("favicon.ico", server_views.favicon, name="favicon"),  # where browsers look without a page's link
    path("health/", server_views.health_page, name="health"),
    path("health.json", server_views.health_json, name="health-json"),
    path("analysis/", site_views.analysis_upload, name="analysis"),
    path("analysis/<str:digest>/", site_views.analysis_report, name="analysis-report"),
    path("analysis/<str:digest>/report.zip", site_views.analysis_report_zip, name="analysis-report-zip"),
    path("admin/", admin.site.urls),
    path("login/", auth_views.LoginView.as_view(), name="login"),
    path("logout/", auth_views.LogoutView.as_view(), name="logout"),
    path("studies/", include("studyapp.researchers.urls")),
    path("leaderboards/", include(leaderboard_urls)),
    path("boards/", include(public_board_urls)),  # public boards, at their unguessable keys
    # Participants: the entry link, the one page they are on, and its steps' forms as
    # participants.path.PATH declares them (/p/KEY/consent/, /p/KEY/rate/, ...).
    path("p/<str:key>/", participant_views.enter, name="participant-enter"),
    path("p/<str:key>/now/", participant_views.page, name="participant-page"),
    *(path(f"p/<str:key>/{step.name}/", participant_views.step_form(step), name=f"participant-{step.name}")
      for step in PATH if step.submit),
    path("p/<str:key>/<path:rest>", participant_views.unknown_page),  # a plain 404, never Django's
]

if settings.SERVE_FILES:
    urlpatterns += [
        path(f"{settings.MEDIA_URL.lstrip('/')}<path:path>", server_views.media_file, name="media"),
        path(f"{settings.STATIC_URL.lstrip('/')}<path:path>", server_views.static_file, name="static"),
    ]
