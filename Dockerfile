# HandSplice app image: serves the browser app on 0.0.0.0:5006 with headless rendering
# (pyrender on Mesa EGL/llvmpipe, OSMesa as fallback, chosen automatically; pyglet headless,
# so no X libraries). Emulated step by step as the non-root user by `tools/fresh-check docker`.
#   docker build -t handsplice .
#   docker run --rm -p 5006:5006 handsplice
FROM python:3.11-slim-bookworm

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    NUMBA_CACHE_DIR=/tmp/numba_cache \
    PIP_NO_CACHE_DIR=1

RUN apt-get update \
 && apt-get install -y --no-install-recommends libgl1 libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6 \
 && rm -rf /var/lib/apt/lists/*

WORKDIR /app
COPY pyproject.toml README.md ./
COPY engine ./engine
COPY webapp ./webapp
COPY sample_data ./sample_data
RUN pip install . \
 && useradd --create-home handsplice \
 && mkdir -p /data/uploads && chown handsplice /data/uploads
USER handsplice

EXPOSE 5006
# 0.0.0.0 inside the container (serve then accepts any websocket origin); samples from /app/sample_data
CMD ["handsplice", "serve", "--address", "0.0.0.0", "--port", "5006", \
     "--sample-dir", "/app/sample_data", "--upload-dir", "/data/uploads"]
