// The model files written while the mesh is still being made: each file as soon as what it holds
// is final (reconstruct/mesh.h's MeshStage), all of them put in place together at the end.
//
//   Mesh mesh;                                     // first: it outlives the writer
//   auto writer = ModelWriter::Start(mesh, dir, "model", formats);
//   ... make the mesh, calling writer->Reached(stage) (or writer->Hook()) as it reaches each stage
//   Expected<std::vector<std::filesystem::path>> files = (*writer)->Finish();
//
// What each file waits for: the STL for the surface; the VRML writes its points at the surface
// and the rest at the colours; the PLY at the colours; the OBJ its vertices at the colours and the
// rest at the uvs; the glTF the uvs and the texture's PNG, which Finish encodes (on its caller's
// thread and pool) once the mesh is done.
// The bytes are WriteModel's (mesh_io.h), which is this writer given a finished mesh.
#pragma once

#include <filesystem>
#include <future>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "base/atomic_file.h"
#include "base/error.h"
#include "reconstruct/io/writer_support.h"
#include "reconstruct/mesh.h"

namespace revolve::reconstruct {

class ModelWriter {
 public:
  // Starts writing `dir`/`basename`.<format> of `mesh` for each of `formats` (kModelFormats;
  // duplicates written once; "obj" also writes .mtl and, with a texture, .png; "wrl" of a mesh
  // with a view-dependent texture is WriteTexturedVrml's), each file on a thread of its own,
  // reading only the fields of `mesh` that Reached has declared final. `mesh` is borrowed: it
  // must outlive the writer and stay at its address, and no field may change once a stage that
  // holds it is reached (until Finish returns or the writer is destroyed). `dir` must exist.
  // Errors: bad_input for an unknown format (nothing started).
  static Expected<std::unique_ptr<ModelWriter>> Start(const Mesh& mesh,
                                                      const std::filesystem::path& dir,
                                                      std::string_view basename,
                                                      const std::vector<std::string>& formats);
  ModelWriter(const ModelWriter&) = delete;
  ModelWriter& operator=(const ModelWriter&) = delete;
  // Without Finish (the mesh failed): the writers stop at their next wait, and no file of this
  // model is put in place (their temporary files are removed; a meridian VRML written already
  // stays). Waits for the writers that are still busy.
  ~ModelWriter();

  // The mesh reached `stage` (MeshStage: in order, each at most once; kUvs promises a texture).
  // Cheap: it wakes the writers that waited for it. Call it on the thread that makes the mesh.
  void Reached(MeshStage stage);
  // Reached, for whoever makes the mesh (the writer must outlive the hook's calls).
  MeshStageHook Hook() {
    return [this](MeshStage stage) { Reached(stage); };
  }

  // The mesh is done (kDone, whether or not Reached said so): encodes the texture's PNG on this
  // thread (its bands on this thread's oneTBB pool), waits for every file, then puts
  // them in place together: each written and fsynced under its temporary name, then renamed over
  // its path in the order returned, then the folder fsynced once. Returns the paths written, in
  // the order of `formats` (.obj, .mtl, .png for "obj"). Errors: io (or aborted, internal) naming
  // the file; then no file of this model is put in place, unless a rename itself fails, which
  // leaves those before it in place. Call it once.
  Expected<std::vector<std::filesystem::path>> Finish();

 private:
  // One writer's files: synced and waiting to be put in place, or (the meridian VRML) in place
  // already.
  struct Output {
    std::vector<std::unique_ptr<AtomicFile>> files;
    std::vector<std::filesystem::path> in_place;
  };
  struct Job;

  ModelWriter(const Mesh& mesh, std::filesystem::path dir, std::string basename,
              std::vector<std::string> formats);
  std::filesystem::path PathOf(std::string_view extension) const;
  bool Wants(std::string_view format) const;
  Expected<Output> WriteFormat(const std::string& format);
  // The texture's PNG: encoded by Finish (on its caller's thread and pool), handed to the glTF
  // writer, written as the .png the .mtl names when "obj" is asked for.
  Expected<Output> WritePng();
  const std::string* WaitForPng();

  const Mesh& mesh_;
  const std::filesystem::path dir_;
  const std::string basename_;
  const std::vector<std::string> formats_;  // each once, in the order asked
  internal::StageGate gate_;
  internal::VertexTexts vertex_texts_;  // the VRML's and the OBJ's, made once
  bool texture_promised_ = false;       // kUvs was reached
  bool finished_ = false;
  // The texture's PNG as Finish encodes it (then the PNG's writer keeps it), and the news that
  // it is set (kept by Finish, or by the destructor of an abandoned model): the PNG's writer may
  // be told of kDone by Reached before Finish encodes it.
  Expected<std::string> encoded_png_ =
      MakeError(ErrorCode::kInternal, "the texture was not encoded");
  std::promise<void> encoded_promise_;
  std::shared_future<void> encoded_ready_;
  bool encoded_kept_ = false;
  void KeepEncoded();
  std::string png_;
  std::promise<const std::string*> png_promise_;
  std::shared_future<const std::string*> png_ready_;
  // Last: destroyed (joined) first.
  std::vector<std::unique_ptr<Job>> jobs_;
};

}  // namespace revolve::reconstruct
