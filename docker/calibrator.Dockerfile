# SofIA calibrator: point-based hand-eye calibration, samples kept in /var/lib/sofia.
# Build from the repository root:  docker build -f docker/calibrator.Dockerfile -t sofia/calibrator .
FROM python:3.11-slim

ENV PYTHONUNBUFFERED=1 PYTHONDONTWRITEBYTECODE=1 \
    PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1

WORKDIR /src
COPY constraints.txt ./
COPY schemas/ schemas/
COPY runtime/ runtime/
COPY replay/ replay/
COPY services/calibrator/ services/calibrator/
RUN pip install -c constraints.txt "./schemas[ros]" ./runtime ./replay ./services/calibrator

# The state directory belongs to the service user, so a fresh named volume mounted there does too.
RUN useradd --create-home --uid 10001 --user-group sofia \
    && mkdir -p /var/lib/sofia/calibrator && chown -R sofia:sofia /var/lib/sofia
USER sofia
WORKDIR /var/lib/sofia/calibrator
# the solver compiled into numba's cache (~/.cache/numba): the first calibration does not compile
RUN python -c "from sofia_calibrator.fitting.warm import warm_kernels; warm_kernels()"
CMD ["sofia", "calibrator", "serve", "--state-dir", "/var/lib/sofia/calibrator"]
