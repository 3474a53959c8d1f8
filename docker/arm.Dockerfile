# SofIA arm: the Franka robot through franky (libfranka), flange pose and joint states on the bus.
# sofia-arm with its [calibrate] extra (the autonomous calibration needs the calibrator's blob
# extraction and solver: SciPy); no Open3D, no simulator (franky-sim is the [sim] extra).
# The franky-control wheel is built for an FR3 (recent libfranka); a Panda on system image 4.x needs
# franky built against libfranka 0.9.x (see the README, "The arm").
# Build from the repository root:  docker build -f docker/arm.Dockerfile -t sofia/arm .
FROM python:3.11-slim

ENV PYTHONUNBUFFERED=1 PYTHONDONTWRITEBYTECODE=1 \
    PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1

WORKDIR /src
COPY constraints.txt ./
COPY schemas/ schemas/
COPY runtime/ runtime/
COPY replay/ replay/
COPY services/calibrator/ services/calibrator/
COPY services/arm/ services/arm/
RUN pip install -c constraints.txt ./schemas ./runtime ./replay ./services/calibrator "./services/arm[calibrate]"

RUN useradd --create-home --uid 10001 --user-group sofia
USER sofia
WORKDIR /home/sofia
# the calibrator's solver compiled into numba's cache (~/.cache/numba): the first autonomous
# calibration does not compile (~15 s)
RUN python -c "from sofia_calibrator.fitting.warm import warm_kernels; warm_kernels()"
CMD ["sofia", "arm", "serve", "--robot-ip", "172.16.0.2"]
