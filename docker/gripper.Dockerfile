# SofIA gripper: the Dynamixel MX-64 of the Fin-Ray gripper (or its emulator with --emulate).
# Only sofia-schemas, sofia-runtime and sofia-gripper: no Open3D, no SciPy, no ROS message libraries.
# Build from the repository root:  docker build -f docker/gripper.Dockerfile -t sofia/gripper .
FROM python:3.11-slim

ENV PYTHONUNBUFFERED=1 PYTHONDONTWRITEBYTECODE=1 \
    PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1

WORKDIR /src
COPY constraints.txt ./
COPY schemas/ schemas/
COPY runtime/ runtime/
COPY services/gripper/ services/gripper/
RUN pip install -c constraints.txt ./schemas ./runtime ./services/gripper

# dialout owns the USB serial adapters (/dev/ttyUSB*).
RUN useradd --create-home --uid 10001 --user-group --groups dialout sofia
USER sofia
WORKDIR /home/sofia
CMD ["sofia", "gripper", "serve", "--port", "/dev/ttyUSB0"]
