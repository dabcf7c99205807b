//! OBJ reader (placeholder).
use super::Mesh;

pub(super) fn parse(_bytes: &[u8]) -> Result<Mesh, String> {
    Err("OBJ reading is not implemented yet".into())
}
