# SofIA for ROS 2: its topics and services offered to nodes using rmw_zenoh, through the router.
# Build from the repository root:  docker build -f docker/ros2.Dockerfile -t sofia/ros2 .
FROM python:3.11-slim

ENV PYTHONUNBUFFERED=1 PYTHONDONTWRITEBYTECODE=1 \
    PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1

WORKDIR /src
COPY constraints.txt ./
COPY schemas/ schemas/
COPY runtime/ runtime/
RUN pip install -c constraints.txt "./schemas[ros]" "./runtime[ros]"

RUN useradd --create-home --uid 10001 --user-group sofia
USER sofia
WORKDIR /home/sofia
CMD ["sofia", "ros2", "serve"]
