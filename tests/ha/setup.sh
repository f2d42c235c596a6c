#!/usr/bin/env bash
# Home Assistant core in its own virtual environment (tests/ha/.venv), apart
# from the doors' clients in .venv: tests/mqtt/home_assistant.rs runs it as
# a real client of gimbal-mqtt. 2024.3 is the newest release for Python
# 3.11; paho-mqtt 1.6.1 is its MQTT integration's own requirement, installed
# here so that Home Assistant runs with --skip-pip.
set -euo pipefail
cd "$(dirname "$0")"
[ -x .venv/bin/python3 ] || python3 -m venv .venv
.venv/bin/pip install --quiet --disable-pip-version-check -r requirements.txt
