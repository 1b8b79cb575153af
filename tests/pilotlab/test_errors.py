from pilotlab.errors import clipped, library_message


def test_a_library_message_keeps_the_reason_on_its_later_lines():
    """ONNX Runtime 1.30 (seen on the GPU host): the first line ends in 'failed:', the reason follows."""
    error = RuntimeError("[ONNXRuntimeError] : 1 : FAIL : Load model from m.onnx failed:\n  External data path "
                         "escapes the model's folder\n\n")
    assert library_message(error) == ("[ONNXRuntimeError] : 1 : FAIL : Load model from m.onnx failed: External "
                                      "data path escapes the model's folder")
    assert len(library_message(RuntimeError("x" * 1000), 200)) == 200


def test_a_library_message_drops_onnx_runtimes_source_line_and_signature():
    error = RuntimeError("[ONNXRuntimeError] : 1 : FAIL : Load model from /tmp/m.onnx failed:/onnxruntime_src/"
                         "onnxruntime/core/graph/model.cc:256 onnxruntime::Model::Model(onnx::ModelProto&&, const "
                         "onnxruntime::PathString&, const onnxruntime::IOnnxRuntimeOpSchemaRegistryList*, const "
                         "onnxruntime::logging::Logger&, const onnxruntime::ModelOptions&) Unsupported model IR "
                         "version: 99, max supported IR version: 14\n")
    assert library_message(error) == ("[ONNXRuntimeError] : 1 : FAIL : Load model from /tmp/m.onnx failed: "
                                      "Unsupported model IR version: 99, max supported IR version: 14")


def test_a_library_message_drops_a_templated_signature_too():
    error = RuntimeError("CUDA failure 100: no CUDA-capable device is detected ; GPU=0 ; hostname=h ; file=/onnxruntime_src/"
                         "onnxruntime/core/providers/cuda/cuda_call.cc:123 std::conditional_t<THRW, void, "
                         "onnxruntime::common::Status> onnxruntime::CudaCall(ERRTYPE, const char*, const char*, "
                         "SUCCTYPE, const char*, const char*, int) [with ERRTYPE = cudaError; bool THRW = true; "
                         "SUCCTYPE = cudaError; std::conditional_t<THRW, void, common::Status> = void] CUDA call failed")
    assert library_message(error).endswith("hostname=h ; file= CUDA call failed")


def test_a_clipped_message_ends_at_a_word_and_says_it_was_cut():
    """Outside test: not-applicable reasons ended mid-word ('... device=c', '... file is corru')."""
    text = "the checkpoint file is corrupt and cannot be read by torch.jit.load at all"
    assert clipped(text, 40) == "the checkpoint file is corrupt and…" and clipped(text, 200) == text
    assert len(clipped("x" * 300, 200)) == 200 and clipped("x" * 300, 200).endswith("x…")
