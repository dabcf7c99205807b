//! PLY reader (placeholder until the fast reader lands).
use super::Mesh;

pub(super) fn parse(_bytes: &[u8]) -> Result<Mesh, String> {
    Err("PLY reading is not implemented yet".into())
}
