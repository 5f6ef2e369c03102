//! The station among what moves: the leader's pace among people, cyclists and vehicles
//! (`yielding`, `stepping_back`), and the route kept aside for people coming the other way
//! down a narrow way (`passing`).

pub(super) mod passing;
pub(super) mod stepping_back;
pub(super) mod yielding;
