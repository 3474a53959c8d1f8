# SofIA camera: the RealSense D435 through librealsense (pyrealsense2), no Open3D (the simulated
# camera, --sim, needs sofia-replay[synth]: run it outside this image or install that extra).
# Build from the repository root:  docker build -f docker/camera.Dockerfile -t sofia/camera .
FROM python:3.11-slim

ENV PYTHONUNBUFFERED=1 PYTHONDONTWRITEBYTECODE=1 \
    PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1

# librealsense's USB backend talks to the camera through libusb.
RUN apt-get update -qq && apt-get install -y -qq --no-install-recommends libusb-1.0-0 \
    && rm -rf /var/lib/apt/lists/*

WORKDIR /src
COPY constraints.txt ./
COPY schemas/ schemas/
COPY runtime/ runtime/
COPY replay/ replay/
COPY services/camera/ services/camera/
RUN pip install -c constraints.txt "./schemas[ros]" ./runtime ./replay ./services/camera

# plugdev: the group the RealSense udev rules give the camera's USB device to.
RUN groupadd --system plugdev 2>/dev/null || true; \
    useradd --create-home --uid 10001 --user-group --groups plugdev sofia
USER sofia
WORKDIR /home/sofia
# the registration and cloud writer compiled into numba's cache (~/.cache/numba): the camera starts at once
RUN python -c "from sofia_camera.pipeline import warm_kernels; warm_kernels()"
CMD ["sofia", "camera", "serve"]
