// The language-model half of the GPU check (scripts/gpu-check/run.sh): a decision-sized
// llama.cpp workload timed with every layer on the CPU and with every layer offloaded, using
// the llama.cpp that aeris links (llama-cpp-sys-2's vendored sources) and the model a
// reasoning role loads. It stands in for `aeris bench models --accelerator cuda:0` where no
// Rust toolchain exists to build aeris with `--features cuda` (a GPU machine without one).
//
//   llama_offload MODEL.gguf NGL THREADS PROMPT_TOKENS GEN_TOKENS REPEATS
//
// Prints one line: the prompt's evaluation (ms), the generation (tokens/s) and one
// decision's latency (prompt + generation, ms), each the median over REPEATS after a
// warm-up.
#include "llama.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

static double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0 : v[v.size() / 2];
}

static void quiet(ggml_log_level, const char *, void *) {}

int main(int argc, char ** argv) {
    if (argc != 7) {
        std::fprintf(stderr, "usage: %s MODEL NGL THREADS PROMPT_TOKENS GEN_TOKENS REPEATS\n", argv[0]);
        return 2;
    }
    const char * path = argv[1];
    const int ngl = std::atoi(argv[2]), threads = std::atoi(argv[3]);
    const int n_prompt = std::atoi(argv[4]), n_gen = std::atoi(argv[5]), repeats = std::atoi(argv[6]);
    llama_log_set(quiet, nullptr);
    llama_backend_init();
    llama_model_params mp = llama_model_default_params();
    mp.n_gpu_layers = ngl;
    mp.split_mode = LLAMA_SPLIT_MODE_NONE;
    mp.main_gpu = 0;
    auto t0 = std::chrono::steady_clock::now();
    llama_model * model = llama_model_load_from_file(path, mp);
    if (!model) {
        std::fprintf(stderr, "cannot load %s\n", path);
        return 1;
    }
    llama_context_params cp = llama_context_default_params();
    cp.n_ctx = 2048;
    cp.n_batch = 512;
    cp.n_threads = threads;
    cp.n_threads_batch = threads;
    llama_context * ctx = llama_init_from_model(model, cp);
    if (!ctx) {
        std::fprintf(stderr, "cannot create a context\n");
        return 1;
    }
    const double load_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const llama_vocab * vocab = llama_model_get_vocab(model);
    // a prompt of the size of a decision's (mission brief, observation, previous decision)
    std::string text;
    while ((int) text.size() < n_prompt * 6) {
        text += "The drone flies north at 12 m altitude toward the LAKE VIEW sign, then turns east "
                "past the red roof and lands beside the blue water tower. ";
    }
    std::vector<llama_token> tokens(text.size() + 16);
    const int n = llama_tokenize(vocab, text.c_str(), (int32_t) text.size(), tokens.data(), (int32_t) tokens.size(), true, false);
    if (n < n_prompt) {
        std::fprintf(stderr, "tokenized only %d tokens\n", n);
        return 1;
    }
    tokens.resize(n_prompt);
    llama_sampler * greedy = llama_sampler_init_greedy();
    std::vector<double> prompt_ms, gen_tps, decision_ms;
    for (int r = 0; r <= repeats; r++) {
        llama_memory_clear(llama_get_memory(ctx), true);
        auto a = std::chrono::steady_clock::now();
        if (llama_decode(ctx, llama_batch_get_one(tokens.data(), (int32_t) tokens.size())) != 0) {
            std::fprintf(stderr, "prompt decode failed\n");
            return 1;
        }
        llama_token next = llama_sampler_sample(greedy, ctx, -1);
        auto b = std::chrono::steady_clock::now();
        for (int g = 0; g < n_gen; g++) {
            if (llama_decode(ctx, llama_batch_get_one(&next, 1)) != 0) {
                std::fprintf(stderr, "generation decode failed\n");
                return 1;
            }
            next = llama_sampler_sample(greedy, ctx, -1);
        }
        auto c = std::chrono::steady_clock::now();
        if (r == 0) {
            continue; // warm-up
        }
        const double p = std::chrono::duration<double, std::milli>(b - a).count();
        const double g = std::chrono::duration<double, std::milli>(c - b).count();
        prompt_ms.push_back(p);
        gen_tps.push_back(n_gen / (g / 1000.0));
        decision_ms.push_back(p + g);
    }
    std::printf("ngl=%d threads=%d gpu_offload=%s load_ms=%.0f prompt_tokens=%d prompt_ms=%.1f gen_tokens=%d gen_tok_s=%.1f decision_ms=%.1f\n",
                ngl, threads, llama_supports_gpu_offload() ? "yes" : "no", load_ms, n_prompt,
                median(prompt_ms), n_gen, median(gen_tps), median(decision_ms));
    llama_sampler_free(greedy);
    llama_free(ctx);
    llama_model_free(model);
    return 0;
}
