# SofIA live view: a Foxglove WebSocket server fed from the bus (open ws://<host>:8765 in Foxglove).
# Build from the repository root:  docker build -f docker/viz.Dockerfile -t sofia/viz .
FROM python:3.11-slim

ENV PYTHONUNBUFFERED=1 PYTHONDONTWRITEBYTECODE=1 \
    PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1

WORKDIR /src
COPY constraints.txt ./
COPY schemas/ schemas/
COPY runtime/ runtime/
COPY services/viz/ services/viz/
RUN pip install -c constraints.txt "./schemas[ros]" ./runtime ./services/viz

RUN useradd --create-home --uid 10001 --user-group sofia
USER sofia
WORKDIR /home/sofia
CMD ["sofia", "viz", "serve", "--host", "0.0.0.0"]
