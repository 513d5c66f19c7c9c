//! The asset resolver a USD import opens its layers through: the filesystem resolver of the `openusd` crate,
//! with every file it opens recorded (for `files_read`, so that an up-to-date check covers every layer), each
//! held to the import's byte limit before it is read, and every `.usdz` package checked to store its files
//! uncompressed, as the USDZ specification requires: a package's entries then take no more bytes than the
//! package itself, so no entry can expand into more memory than the file holds (a zip bomb is refused).

use std::cell::RefCell;
use std::collections::BTreeSet;
use std::io;
use std::path::{Path, PathBuf};
use std::rc::Rc;

use openusd::ar::{self, Asset, DefaultResolver, ResolvedPath, Resolver};

/// What the resolver saw, shared with the import that opened the stage.
#[derive(Debug, Default)]
pub(super) struct Opened {
    /// Every file opened, in the order first opened (a package once, however many of its entries were read).
    pub files: Vec<PathBuf>,
    /// Bytes of the files opened so far.
    pub bytes: u64,

    seen: BTreeSet<PathBuf>,
}

/// [`DefaultResolver`] with a byte budget and a record of what it opened.
pub(super) struct BoundedResolver {
    inner: DefaultResolver,
    /// The largest total of bytes the layers may take (`ImportLimits::max_input_bytes`).
    max_bytes: u64,
    opened: Rc<RefCell<Opened>>,
}

impl BoundedResolver {
    pub(super) fn new(max_bytes: u64) -> (BoundedResolver, Rc<RefCell<Opened>>) {
        let opened = Rc::new(RefCell::new(Opened::default()));
        (BoundedResolver { inner: DefaultResolver::new(), max_bytes, opened: opened.clone() }, opened)
    }

    /// Records `file` and counts its bytes against the budget; a package's entries are checked once.
    fn admit(&self, file: &Path) -> io::Result<()> {
        if self.opened.borrow().seen.contains(file) {
            return Ok(());
        }
        let metadata = std::fs::metadata(file)?;
        if !metadata.is_file() {
            return Err(io::Error::other(format!("{} is not a regular file", file.display())));
        }
        let total = self.opened.borrow().bytes.saturating_add(metadata.len());
        if total > self.max_bytes {
            return Err(io::Error::other(format!(
                "{}: with the layers read before it, {total} bytes exceed the import limit of {} bytes (raise it \
                 with --max-input-bytes)",
                file.display(),
                self.max_bytes
            )));
        }
        if is_package(file) {
            check_package(file)?;
        }
        let mut opened = self.opened.borrow_mut();
        opened.seen.insert(file.to_path_buf());
        opened.files.push(file.to_path_buf());
        opened.bytes = total;
        Ok(())
    }
}

/// Whether `file` names a USDZ package.
fn is_package(file: &Path) -> bool {
    file.extension().is_some_and(|e| e.eq_ignore_ascii_case("usdz"))
}

/// A USDZ package's entries must be stored uncompressed (the USDZ specification; also what bounds the memory an
/// entry takes by the package's size) and lie within it.
fn check_package(file: &Path) -> io::Result<()> {
    let reader = std::fs::File::open(file)?;
    let size = reader.metadata()?.len();
    let mut archive = zip::ZipArchive::new(reader)
        .map_err(|e| io::Error::other(format!("{}: not a readable USDZ package (zip): {e}", file.display())))?;
    for index in 0..archive.len() {
        let entry = archive
            .by_index_raw(index)
            .map_err(|e| io::Error::other(format!("{}: entry {index}: {e}", file.display())))?;
        if entry.compression() != zip::CompressionMethod::Stored {
            return Err(io::Error::other(format!(
                "{}: entry '{}' is compressed ({}); a USDZ package stores its files uncompressed",
                file.display(),
                entry.name(),
                entry.compression()
            )));
        }
        if entry.size() > size {
            return Err(io::Error::other(format!(
                "{}: entry '{}' declares {} bytes, more than the package's {size}",
                file.display(),
                entry.name(),
                entry.size()
            )));
        }
    }
    Ok(())
}

impl Resolver for BoundedResolver {
    fn create_identifier(&self, asset_path: &str, anchor: Option<&ResolvedPath>) -> String {
        self.inner.create_identifier(asset_path, anchor)
    }

    /// MaterialX documents are never resolved: they hold materials, which a BVH does not need, and no layer
    /// format reads them; composition records each as unresolved and the import lists it as unread.
    fn resolve(&self, asset_path: &str) -> Option<ResolvedPath> {
        if super::is_material_x(asset_path) {
            return None;
        }
        self.inner.resolve(asset_path)
    }

    fn resolve_for_new_asset(&self, asset_path: &str) -> Option<ResolvedPath> {
        self.inner.resolve_for_new_asset(asset_path)
    }

    fn open_asset(&self, resolved_path: &ResolvedPath) -> io::Result<Box<dyn Asset>> {
        let text = resolved_path.to_str().unwrap_or_default();
        let file = match ar::split_package_relative_path_outer(text) {
            Some((package, _)) if ar::is_package_relative_path(text) => PathBuf::from(package),
            _ => resolved_path.to_path_buf(),
        };
        self.admit(&file)?;
        self.inner.open_asset(resolved_path)
    }

    fn identity(&self) -> String {
        format!("bvhc-bounded({})", self.inner.identity())
    }
}
