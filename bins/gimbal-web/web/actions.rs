//! What a signed-in user does through the API (the `POST /api/...` routes
//! of [`super`] after sign-in): move, stop, home, go to a point of the
//! map, save and recall presets, and as an administrator start or stop
//! gcud's tours and release a gimbal. Each handler is allowed by role and
//! reads its JSON body through `Web::post`, drives the gimbal's session,
//! and answers with [`super::answer`] or a [`Failure`].

use std::sync::Arc;

use axum::Router;
use axum::extract::State;
use axum::http::{HeaderMap, StatusCode};
use axum::response::Response;
use axum::routing::post;
use sagebrush_client::connection::proportional_speed;
use sagebrush_client::governance::tour_state_name;
use sagebrush_client::presets;
use sagebrush_client::session::{Axes, Drive, Velocity};
use sagebrush_protocol::Command;
use serde::Deserialize;
use serde_json::json;
use tracing::info;

use super::{Failure, Shared, Web, answer, bad, failed};
use crate::config::Role;

/// The actions' routes, each a `POST` with a JSON body.
pub(super) fn routes() -> Router<Arc<Web>> {
    Router::new()
        .route("/api/move", post(do_move))
        .route("/api/stop", post(stop))
        .route("/api/home", post(home))
        .route("/api/goto", post(go_to))
        .route("/api/preset/save", post(preset_save))
        .route("/api/preset/go", post(preset_go))
        .route("/api/tour", post(tour))
        .route("/api/release", post(release))
}

#[derive(Deserialize)]
struct MoveBody {
    gimbal: usize,
    pan: i8,
    tilt: i8,
    speed: f64,
}

/// A button's direction (-1, 0, 1) at `speed` (0..=1): 0 leaves the axis alone.
fn drive(sign: i8, speed: f64) -> Option<Drive<sagebrush_protocol::Speed>> {
    (sign != 0).then(|| Drive::signed(f64::from(sign), |_| proportional_speed(speed)))
}

async fn do_move(State(w): Shared, headers: HeaderMap, bytes: axum::body::Bytes) -> Result<Response, Failure> {
    let (who, b): (_, MoveBody) = w.post(
        &headers,
        &bytes,
        (Role::Operator, "move"),
        "{gimbal, pan: -1|0|1, tilt: -1|0|1, speed: 0..1}",
    )?;
    if !(b.speed > 0.0 && b.speed <= 1.0) || b.pan.abs() > 1 || b.tilt.abs() > 1 {
        return Err(bad(format!(
            "expected pan and tilt in -1..=1 and speed in (0, 1], found pan {}, tilt {}, speed {}",
            b.pan, b.tilt, b.speed
        )));
    }
    let g = w.gimbal(b.gimbal)?;
    if b.pan == 0 && b.tilt == 0 {
        g.session.stop(Axes::PAN_TILT).await.map_err(failed)?;
    } else {
        let velocity = Velocity {
            pan: drive(b.pan, b.speed),
            tilt: drive(b.tilt, b.speed),
            zoom: None,
        };
        g.session
            .acting_for(Some(&who.user))
            .velocity(velocity, Some(w.lease), &format!("web {}", who.user))
            .await
            .map_err(failed)?;
    }
    Ok(answer(json!({})))
}

#[derive(Deserialize)]
struct GimbalBody {
    gimbal: usize,
}

async fn stop(State(w): Shared, headers: HeaderMap, bytes: axum::body::Bytes) -> Result<Response, Failure> {
    let (_, b): (_, GimbalBody) = w.post(&headers, &bytes, (Role::Operator, "stop"), "{gimbal}")?;
    w.gimbal(b.gimbal)?.session.stop(Axes::PAN_TILT).await.map_err(failed)?;
    Ok(answer(json!({})))
}

async fn home(State(w): Shared, headers: HeaderMap, bytes: axum::body::Bytes) -> Result<Response, Failure> {
    let (who, b): (_, GimbalBody) = w.post(&headers, &bytes, (Role::Operator, "move"), "{gimbal}")?;
    let g = w.gimbal(b.gimbal)?;
    g.session.acting_for(Some(&who.user)).home().await.map_err(failed)?;
    Ok(answer(json!({})))
}

#[derive(Deserialize)]
struct GoToBody {
    gimbal: usize,
    pan: f64,
    tilt: f64,
}

async fn go_to(State(w): Shared, headers: HeaderMap, bytes: axum::body::Bytes) -> Result<Response, Failure> {
    let (who, b): (_, GoToBody) = w.post(
        &headers,
        &bytes,
        (Role::Operator, "move"),
        "{gimbal, pan, tilt} in degrees",
    )?;
    let g = w.gimbal(b.gimbal)?;
    let within = |v: f64, (low, high): (f64, f64)| v.is_finite() && v >= low && v <= high;
    if !within(b.pan, g.config.pan_deg) || !within(b.tilt, g.config.tilt_deg) {
        return Err(bad(format!(
            "pan {}° tilt {}° is outside the travel of {}: pan {}°..{}°, tilt {}°..{}°",
            b.pan,
            b.tilt,
            g.config.name,
            g.config.pan_deg.0,
            g.config.pan_deg.1,
            g.config.tilt_deg.0,
            g.config.tilt_deg.1
        )));
    }
    g.session
        .acting_for(Some(&who.user))
        .go_to_degrees(Some(b.pan), Some(b.tilt))
        .await
        .map_err(failed)?;
    Ok(answer(json!({})))
}

#[derive(Deserialize)]
struct SaveBody {
    gimbal: usize,
    name: String,
}

async fn preset_save(State(w): Shared, headers: HeaderMap, bytes: axum::body::Bytes) -> Result<Response, Failure> {
    let (who, b): (_, SaveBody) = w.post(&headers, &bytes, (Role::Operator, "save presets"), "{gimbal, name}")?;
    let g = w.gimbal(b.gimbal)?;
    let name = b.name.trim();
    if name.is_empty() || name.chars().count() > presets::MAX_NAME {
        return Err(bad(format!(
            "expected a preset name of 1 to {} characters",
            presets::MAX_NAME
        )));
    }
    if let Some(c) = presets::hidden_char(name) {
        return Err(bad(format!(
            "a preset name may not hold U+{:04X} (a control or invisible formatting character)",
            u32::from(c)
        )));
    }
    let list = w.presets.list(&g.config.name);
    // Saving under a name in use moves that preset here.
    // Never a preset gcud's park or tours recall (`~B` says which).
    let reserved = g.session.rules().await.map(|r| r.reserved).unwrap_or_default();
    let n = match list.iter().find(|(n, m)| m == name && !reserved.contains(n)) {
        Some((n, _)) => *n,
        None => w.presets.free(&g.config.name, &reserved).ok_or_else(|| {
            bad(format!(
                "{} has no free preset number (256 named or gcud's)",
                g.config.name
            ))
        })?,
    };
    g.session
        .acting_for(Some(&who.user))
        .send(Command::StorePreset(n))
        .await
        .map_err(failed)?;
    w.presets
        .set(&g.config.name, n, Some(name))
        .map_err(|e| Failure(StatusCode::INTERNAL_SERVER_ERROR, e))?;
    Ok(answer(json!({ "n": n })))
}

#[derive(Deserialize)]
struct TourBody {
    name: String,
    start: bool,
}

/// Starts or stops one of gcud's tours (`~T+`, `~T-`): what became of it.
async fn tour(State(w): Shared, headers: HeaderMap, bytes: axum::body::Bytes) -> Result<Response, Failure> {
    let (who, b): (_, TourBody) = w.post(
        &headers,
        &bytes,
        (Role::Administrator, "start or stop tours"),
        "{name, start: true|false}",
    )?;
    let session = w
        .tour_session(&b.name)
        .ok_or_else(|| bad(format!("gcud has no tour named {:?}", b.name)))?;
    let outcome = session.tour(&b.name, b.start).await.map_err(failed)?;
    info!(user = %who.user, tour = %b.name, start = b.start, state = tour_state_name(outcome.state), "tour");
    w.refresh_tours().await;
    Ok(answer(json!({
        "state": tour_state_name(outcome.state),
        "waiting_for": outcome.waiting_for,
    })))
}

/// Releases control of a gimbal (`~R`): gcud refuses it while a link of
/// higher priority than gimbal-web's holds it (its words, HTTP 409).
async fn release(State(w): Shared, headers: HeaderMap, bytes: axum::body::Bytes) -> Result<Response, Failure> {
    let (who, b): (_, GimbalBody) = w.post(&headers, &bytes, (Role::Administrator, "release a gimbal"), "{gimbal}")?;
    let g = w.gimbal(b.gimbal)?;
    g.session.acting_for(Some(&who.user)).release().await.map_err(failed)?;
    info!(user = %who.user, gimbal = %g.config.name, "released");
    Ok(answer(json!({ "released": true })))
}

#[derive(Deserialize)]
struct PresetBody {
    gimbal: usize,
    n: u8,
}

async fn preset_go(State(w): Shared, headers: HeaderMap, bytes: axum::body::Bytes) -> Result<Response, Failure> {
    let (who, b): (_, PresetBody) = w.post(&headers, &bytes, (Role::Operator, "recall presets"), "{gimbal, n}")?;
    let g = w.gimbal(b.gimbal)?;
    g.session
        .acting_for(Some(&who.user))
        .go_to_preset(b.n)
        .await
        .map_err(failed)?;
    Ok(answer(json!({})))
}
