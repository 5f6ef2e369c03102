//! What runs beside a live run (`run`, `robots`, `sim --realtime`): the operator's
//! console, the site's feeds (localization and scans, in and out), the recording and live
//! stream, the control loop's timing, and what is wrong with the link, in words.

pub mod admission;
pub mod console;
pub mod diagnosis;
pub mod feeds;
pub mod recording;
pub mod timing;
