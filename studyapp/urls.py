"""URL map of the study app."""

from django.conf import settings
from django.contrib import admin
from django.urls import path

from studyapp import views

urlpatterns = [
    path("", views.gallery, name="gallery"),
    path("health/", views.health_page, name="health"),
    path("health.json", views.health_json, name="health-json"),
    path("analysis/", views.analysis_upload, name="analysis"),
    path("analysis/<str:digest>/", views.analysis_report, name="analysis-report"),
    path("admin/", admin.site.urls),
]

if settings.SERVE_FILES:
    urlpatterns += [
        path(f"{settings.MEDIA_URL.lstrip('/')}<path:path>", views.media_file, name="media"),
        path(f"{settings.STATIC_URL.lstrip('/')}<path:path>", views.static_file, name="static"),
    ]
