"""URL map of the board pages: the researcher's under ``leaderboards/``, the public one under ``boards/``."""

from django.urls import path

from studyapp.leaderboards import views

researcher_urls = [
    path("", views.leaderboard_list, name="leaderboard-list"),
    path("<int:pk>/", views.leaderboard_page, name="leaderboard"),
    path("<int:pk>/settings/", views.leaderboard_settings, name="leaderboard-settings"),
    path("<int:pk>/rounds/", views.leaderboard_add_round, name="leaderboard-add-round"),
    path("<int:pk>/rounds/<int:round_pk>/fit/", views.leaderboard_round_fit, name="leaderboard-round-fit"),
    path("<int:pk>/rounds/<int:round_pk>/remove/", views.leaderboard_remove_round, name="leaderboard-remove-round"),
    path("<int:pk>/leaderboard.csv", views.leaderboard_csv, name="leaderboard-csv"),
]

public_urls = [
    path("<str:key>/", views.public_page, name="leaderboard-public"),
    path("<str:key>/leaderboard.csv", views.public_csv, name="leaderboard-public-csv"),
]
