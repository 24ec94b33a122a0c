"""Researcher accounts: a login that may use the study pages and the admin, which shows each
researcher the rows of their own studies only (``studyapp.admin``)."""

from django.contrib.auth.models import Permission, User
from django.contrib.auth.password_validation import (
    CommonPasswordValidator,
    MinimumLengthValidator,
    UserAttributeSimilarityValidator,
    validate_password,
)

# A researcher's login guards every participant's answers, so its password is held to
# Django's checks even where the settings name none (the demo's and the tests' accounts).
PASSWORD_VALIDATORS = (MinimumLengthValidator(12), CommonPasswordValidator(), UserAttributeSimilarityValidator())


def grant_researcher_rights(user: User) -> None:
    """Make ``user`` a researcher: staff (the admin is one of the researcher's pages) with the
    study app's permissions."""
    if not user.is_staff:
        user.is_staff = True
        user.save(update_fields=["is_staff"])
    user.user_permissions.set(Permission.objects.filter(content_type__app_label="studyapp"))


def check_researcher_password(password: str, username: str, email: str) -> None:
    """Raise Django's ValidationError, with every reason, for a password too weak for a researcher."""
    validate_password(password, User(username=username, email=email), password_validators=PASSWORD_VALIDATORS)


def create_researcher(username: str, email: str, password: str) -> User:
    """A new researcher account; the caller has checked that the name is free and the password strong."""
    user = User.objects.create_user(username, email=email, password=password, is_staff=True)
    grant_researcher_rights(user)
    return user
