//! The robots among themselves: no robot driven into another where its ring cannot see
//! it (`spacing`), the leader's way blocked by its own follower (`way`), the line's
//! followers in slot order (`line_order`), followers sent round what holds them
//! (`detour`).

pub(super) mod desk;
pub(super) mod detour;
pub(super) mod line_order;
pub(super) mod spacing;
pub(super) mod way;
