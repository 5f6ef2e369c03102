//! What runs beside a live run (`run`, `robots`, `sim --realtime`): the operator's
//! console, the site's feeds (localization and scans, in and out), the recording and live
//! stream, and the control loop's timing.

pub mod console;
pub mod feeds;
pub mod recording;
pub mod timing;
