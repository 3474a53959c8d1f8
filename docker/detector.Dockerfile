# SofIA detector: finds the object on the board in every point cloud (Open3D).
# Build from the repository root:  docker build -f docker/detector.Dockerfile -t sofia/detector .
FROM python:3.11-slim

# Open3D links libusb-1.0 and libgomp at import time.
RUN apt-get update \
    && apt-get install -y --no-install-recommends libusb-1.0-0 libgomp1 \
    && rm -rf /var/lib/apt/lists/*

ENV PYTHONUNBUFFERED=1 PYTHONDONTWRITEBYTECODE=1 \
    PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1

WORKDIR /src
COPY constraints.txt ./
COPY schemas/ schemas/
COPY runtime/ runtime/
COPY replay/ replay/
COPY services/detector/ services/detector/
RUN pip install -c constraints.txt "./schemas[ros]" ./runtime ./replay ./services/detector

# The lab board as the default; compose mounts ./config/board.yaml over it.
COPY config/board.yaml /etc/sofia/board.yaml

RUN useradd --create-home --uid 10001 --user-group sofia
USER sofia
WORKDIR /home/sofia
CMD ["sofia", "detector", "serve", "--board", "/etc/sofia/board.yaml"]
