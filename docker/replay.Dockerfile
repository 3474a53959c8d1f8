# SofIA replayer: streams an MCAP recording onto the bus (develop without the robot).
# Build from the repository root:  docker build -f docker/replay.Dockerfile -t sofia/replay .
FROM python:3.11-slim

ENV PYTHONUNBUFFERED=1 PYTHONDONTWRITEBYTECODE=1 \
    PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1

WORKDIR /src
COPY constraints.txt ./
COPY schemas/ schemas/
COPY runtime/ runtime/
COPY replay/ replay/
RUN pip install -c constraints.txt "./schemas[ros]" ./runtime ./replay

RUN useradd --create-home --uid 10001 --user-group sofia
USER sofia
WORKDIR /home/sofia
CMD ["sofia", "replay", "play", "/recordings/scenes.mcap", "--loop"]
