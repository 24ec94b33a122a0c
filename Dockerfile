# The image behind compose.yaml's web, worker and migrate services.
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1

# torch goes in first and pinned, so `pip install .` finds it satisfied. Point
# TORCH_INDEX_URL at a CPU-only wheel index for a much smaller image.
ARG TORCH_INDEX_URL=""
RUN pip install torch==2.13.0 ${TORCH_INDEX_URL:+--index-url "$TORCH_INDEX_URL"}

# imageio-ffmpeg ships its own ffmpeg binary, so no system ffmpeg is needed. pg_dump and
# pg_restore are for `manage.py backup` and `restore`, of compose's PostgreSQL major version
# (PostgreSQL's own packages: a newer client writes dumps that an older server cannot load,
# an older one refuses to dump a newer server).
ARG POSTGRES_MAJOR=16
RUN apt-get update && apt-get install -y --no-install-recommends ca-certificates postgresql-common \
    && /usr/share/postgresql-common/pgdg/apt.postgresql.org.sh -y \
    && apt-get install -y --no-install-recommends "postgresql-client-${POSTGRES_MAJOR}" \
    && rm -rf /var/lib/apt/lists/*
WORKDIR /app
COPY . .
RUN pip install .

# Static files are collected at build time; a throwaway var folder keeps the
# embedded defaults that settings create out of the image.
ENV STATIC_ROOT=/app/static
RUN DEBUG=1 STUDYAPP_VAR_DIR=/tmp/build-var python manage.py collectstatic --noinput \
    && rm -rf /tmp/build-var

# /data/media is where compose mounts the shared media volume; a new named
# volume takes this folder's owner, so the app user can write to it.
RUN useradd --create-home --uid 1000 app \
    && mkdir -p /data/media /data/var /data/static /data/backups \
    && chown -R app:app /data
USER app
ENV MEDIA_ROOT=/data/media \
    STUDYAPP_VAR_DIR=/data/var

EXPOSE 8000
CMD ["gunicorn", "studyapp.server.wsgi", "--bind", "0.0.0.0:8000", "--access-logfile", "-"]
