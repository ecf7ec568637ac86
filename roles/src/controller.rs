//! Placeholder: being implemented.
use aeris_runtime::{CycleOutcome, CycleReport, Role, RoleContext, RoleError};
/// Placeholder.
pub struct ControllerRole;
impl Role for ControllerRole {
    fn new(_ctx: &mut RoleContext) -> Result<Self, RoleError> {
        Err(RoleError::Fatal("not built yet".into()))
    }
    fn period(&self) -> core::time::Duration {
        core::time::Duration::from_millis(100)
    }
    fn cycle(
        &mut self,
        _ctx: &mut RoleContext,
        _r: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        Ok(CycleOutcome::Idle)
    }
}
