#include "reconstruct/io/model_writer.h"

#include <pthread.h>

#include <algorithm>
#include <functional>
#include <system_error>
#include <thread>

#include <fmt/format.h>

#include "base/png_encode.h"
#include "reconstruct/io/mesh_io.h"
#include "reconstruct/meridian/meridian_vrml.h"

namespace revolve::reconstruct {

namespace fs = std::filesystem;

struct ModelWriter::Job {
  std::string name;  // the thread's, for profilers and top -H: "write png", "write obj", ...
  std::function<Expected<Output>()> run;
  Expected<Output> output = MakeError(ErrorCode::kInternal, "a model writer did not run");
  // Empty when no thread could be had: the job then runs in Finish.
  std::jthread thread;
};

namespace {

// A temporary file for `path`, opened.
Expected<std::unique_ptr<AtomicFile>> OpenFile(const fs::path& path) {
  auto file = std::make_unique<AtomicFile>(path);
  if (Expected<void> opened = file->Open(); !opened) return std::unexpected(opened.error());
  return file;
}

}  // namespace

Expected<std::unique_ptr<ModelWriter>> ModelWriter::Start(const Mesh& mesh, const fs::path& dir,
                                                          std::string_view basename,
                                                          const std::vector<std::string>& formats) {
  std::vector<std::string> unique;
  for (const std::string& format : formats) {
    if (!IsModelFormat(format)) {
      return MakeError(
          ErrorCode::kBadInput,
          fmt::format("unknown model format \"{}\" (expected ply, obj, stl, glb or wrl)", format));
    }
    if (std::find(unique.begin(), unique.end(), format) == unique.end()) unique.push_back(format);
  }
  std::unique_ptr<ModelWriter> writer(
      new ModelWriter(mesh, dir, std::string(basename), std::move(unique)));
  ModelWriter& w = *writer;
  // The PNG's job first: when it has no thread of its own, Finish runs it before the glTF's.
  if (w.Wants("obj") || w.Wants("glb")) {
    w.jobs_.push_back(std::make_unique<Job>());
    w.jobs_.back()->name = "write png";
    w.jobs_.back()->run = [&w] { return w.WritePng(); };
  }
  for (const std::string& format : w.formats_) {
    w.jobs_.push_back(std::make_unique<Job>());
    w.jobs_.back()->name = "write " + format;
    w.jobs_.back()->run = [&w, &format] { return w.WriteFormat(format); };
  }
  // Every file at once, each on a thread of its own rather than one of the pool's: a writer
  // spends much of its time waiting, for its stage or for the disk (direct I/O, fsync), and a pool
  // thread waiting would leave a core idle.
  for (const std::unique_ptr<Job>& job : w.jobs_) {
    try {
      job->thread = std::jthread([&job = *job] {
        ::pthread_setname_np(::pthread_self(), job.name.c_str());
        job.output = job.run();
      });
    } catch (const std::system_error&) {
      // No thread to be had: Finish runs it.
    }
  }
  return writer;
}

ModelWriter::ModelWriter(const Mesh& mesh, fs::path dir, std::string basename,
                         std::vector<std::string> formats)
    : mesh_(mesh),
      dir_(std::move(dir)),
      basename_(std::move(basename)),
      formats_(std::move(formats)),
      encoded_ready_(encoded_promise_.get_future().share()),
      png_ready_(png_promise_.get_future().share()) {}

ModelWriter::~ModelWriter() {
  if (!finished_) {
    gate_.Abandon();
    if (!encoded_kept_) {
      encoded_png_ = std::unexpected(internal::AbandonedFile(PathOf("png")));
      KeepEncoded();
    }
    // Those without a thread return at their first wait; the PNG's keeps its promise, which
    // the glTF's thread may be waiting for.
    for (const std::unique_ptr<Job>& job : jobs_) {
      if (!job->thread.joinable()) job->output = job->run();
    }
  }
  for (const std::unique_ptr<Job>& job : jobs_) {
    if (job->thread.joinable()) job->thread.join();
  }
}

void ModelWriter::Reached(MeshStage stage) {
  if (stage == MeshStage::kUvs) texture_promised_ = true;  // read after the gate's lock
  gate_.Reach(stage);
}

fs::path ModelWriter::PathOf(std::string_view extension) const {
  return dir_ / fmt::format("{}.{}", basename_, extension);
}

bool ModelWriter::Wants(std::string_view format) const {
  return std::find(formats_.begin(), formats_.end(), format) != formats_.end();
}

Expected<ModelWriter::Output> ModelWriter::WriteFormat(const std::string& format) {
  const fs::path path = PathOf(format);
  Output output;
  if (format == "wrl") {
    if (!gate_.Wait(MeshStage::kSurface)) return std::unexpected(internal::AbandonedFile(path));
    if (mesh_.HasViewTexture()) {
      // The meridian's view-dependent texture: its images (<basename>_texNN.jpg), then the .wrl,
      // each put in place as it is written.
      if (!gate_.Wait(MeshStage::kDone)) return std::unexpected(internal::AbandonedFile(path));
      Expected<std::vector<fs::path>> written = WriteTexturedVrml(mesh_, path, 0.001);
      if (!written) return std::unexpected(written.error());
      output.in_place = std::move(*written);
      return output;
    }
  }
  Expected<std::unique_ptr<AtomicFile>> file = OpenFile(path);
  if (!file) return std::unexpected(file.error());
  // The vertices' texts made once when both the VRML and the OBJ write them; one of them alone
  // writes its numbers straight into its file (no 32 bytes a vertex of text held besides).
  internal::VertexTexts* const texts = Wants("wrl") && Wants("obj") ? &vertex_texts_ : nullptr;
  Expected<void> put;
  if (format == "ply") {
    put = internal::PutPly(mesh_, gate_, file->get());
  } else if (format == "stl") {
    put = internal::PutStl(mesh_, gate_, file->get());
  } else if (format == "wrl") {
    put = internal::PutVrml(mesh_, gate_, file->get(), texts);
  } else if (format == "glb") {
    put = internal::PutGlb(
        mesh_, gate_, [this] { return WaitForPng(); }, file->get());
  } else {
    Expected<std::unique_ptr<AtomicFile>> mtl = OpenFile(PathOf("mtl"));
    if (!mtl) return std::unexpected(mtl.error());
    put = internal::PutObj(mesh_, gate_, file->get(), mtl->get(), texts);
    output.files.push_back(std::move(*file));
    file = std::move(*mtl);
  }
  if (!put) return std::unexpected(put.error());
  output.files.push_back(std::move(*file));
  for (const std::unique_ptr<AtomicFile>& f : output.files) {
    if (Expected<void> synced = f->Sync(); !synced) return std::unexpected(synced.error());
  }
  return output;
}

void ModelWriter::KeepEncoded() {
  encoded_kept_ = true;
  encoded_promise_.set_value();
}

const std::string* ModelWriter::WaitForPng() {
  try {
    return png_ready_.get();
  } catch (const std::future_error&) {
    return nullptr;
  }
}

Expected<ModelWriter::Output> ModelWriter::WritePng() {
  // The glTF writer waits for the promise: kept on every way out (null but for a PNG).
  struct Keep {
    std::promise<const std::string*>& promise;
    const std::string* png = nullptr;
    ~Keep() { promise.set_value(png); }
  } keep{png_promise_};
  const fs::path path = PathOf("png");
  if (!gate_.Wait(MeshStage::kDone)) return std::unexpected(internal::AbandonedFile(path));
  Output output;
  if (!mesh_.HasTexture()) {
    if (texture_promised_) {
      return MakeError(ErrorCode::kInternal,
                       fmt::format("{}: the mesh has uvs but no texture image", path.string()));
    }
    return output;
  }
  // Encoded by Finish (once the mesh is done, which Reached may have said before).
  encoded_ready_.wait();
  if (!encoded_png_) return std::unexpected(WithContext(encoded_png_.error(), path.string()));
  png_ = std::move(*encoded_png_);
  keep.png = &png_;
  if (!Wants("obj")) return output;  // the glTF embeds it; no file of its own
  Expected<std::unique_ptr<AtomicFile>> file = OpenFile(path);
  if (!file) return std::unexpected(file.error());
  (*file)->Append(png_);
  if (Expected<void> synced = (*file)->Sync(); !synced) return std::unexpected(synced.error());
  output.files.push_back(std::move(*file));
  return output;
}

Expected<std::vector<fs::path>> ModelWriter::Finish() {
  // The texture's PNG here, on the caller's thread, before the mesh is declared done: its bands
  // then run on every core of the caller's pool (oneTBB gives a writer's own thread an arena of
  // its own, which the pool's threads, busy or asleep, join late: the bands ran on one core).
  if ((Wants("obj") || Wants("glb")) && mesh_.HasTexture()) {
    encoded_png_ = EncodePng(mesh_.texture);
  }
  KeepEncoded();
  Reached(MeshStage::kDone);
  for (const std::unique_ptr<Job>& job : jobs_) {
    if (!job->thread.joinable()) job->output = job->run();
  }
  for (const std::unique_ptr<Job>& job : jobs_) {
    if (job->thread.joinable()) job->thread.join();
  }
  finished_ = true;
  const std::size_t first_format = jobs_.size() - formats_.size();  // 1 after the PNG's job
  Expected<Output>* png = first_format > 0 ? &jobs_.front()->output : nullptr;
  // Each format's output in the order asked, the PNG's (the .png file) after the OBJ's; and the
  // first error in that order, the PNG's before the glTF's (which it causes).
  std::vector<Expected<Output>*> order;
  const Error* error = nullptr;
  const auto add = [&order, &error](Expected<Output>* output) {
    order.push_back(output);
    if (!*output && error == nullptr) error = &output->error();
  };
  for (std::size_t i = 0; i < formats_.size(); ++i) {
    if (formats_[i] == "glb" && !*png && error == nullptr) error = &png->error();
    add(&jobs_[first_format + i]->output);
    if (formats_[i] == "obj") add(png);
  }
  if (error != nullptr) {
    Error failed = *error;
    jobs_.clear();  // removes every temporary file
    return std::unexpected(std::move(failed));
  }
  std::vector<fs::path> written;
  for (Expected<Output>* output : order) {
    for (const fs::path& path : (*output)->in_place) written.push_back(path);
    for (const std::unique_ptr<AtomicFile>& file : (*output)->files) {
      if (Expected<void> published = file->Publish(); !published) {
        jobs_.clear();
        return std::unexpected(published.error());
      }
      written.push_back(file->path());
    }
  }
  // Makes the renames durable (best effort, as AtomicFile::Commit: the files are in place).
  (void)SyncDirectory(dir_);
  jobs_.clear();
  return written;
}

}  // namespace revolve::reconstruct
